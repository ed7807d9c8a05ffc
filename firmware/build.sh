#!/usr/bin/env bash
# Builds the ATmega328P image with PlatformIO, offline, and prints flash/RAM use.
#   output: firmware/.pio/build/uno_wifi/program.elf and program.hex
# Needs `make deps` (Debian gcc-avr/avr-libc, .venv with platformio/scons/pymavlink, and
# deps/post/firmware.sh for the offline tool-scons). Fails if less than 25 % of RAM stays free.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
export PLATFORMIO_CORE_DIR="$here/.pio-core"
export PLATFORMIO_SETTING_ENABLE_TELEMETRY=No
export PLATFORMIO_SETTING_CHECK_PLATFORMIO_INTERVAL=3650
export PLATFORMIO_SETTING_CHECK_PRUNE_SYSTEM_THRESHOLD=0
pio="$root/.venv/bin/pio"
if [ ! -x "$pio" ]; then echo "firmware/build.sh: $pio missing: run 'make deps'"; exit 1; fi
if [ ! -f "$PLATFORMIO_CORE_DIR/packages/tool-scons/scons.py" ]; then bash "$root/deps/post/firmware.sh"; fi
"$pio" run -d "$here" -s
elf="$here/.pio/build/uno_wifi/program.elf"
# RAM = .data + .bss (static); flash = .text + .data.
read -r text data bss < <(avr-size -A -d "$elf" | awk '$1==".text"{t=$2} $1==".data"{d=$2} $1==".bss"{b=$2} END{print t+0, d+0, b+0}')
flash=$((text + data)); ram=$((data + bss))
flash_max=32256; ram_max=2048
printf 'firmware: %s\n' "$elf"
printf 'firmware: flash %d / %d bytes (%d %%), RAM (static .data+.bss) %d / %d bytes (%d %%), %d bytes free for the stack\n' \
  "$flash" "$flash_max" $((100 * flash / flash_max)) "$ram" "$ram_max" $((100 * ram / ram_max)) $((ram_max - ram))
if [ $((ram * 4)) -gt $((ram_max * 3)) ]; then
  echo "firmware: FAIL: static RAM use above 75 % (keep >= 25 % free)"; exit 1
fi
