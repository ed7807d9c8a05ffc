#!/usr/bin/env bash
# Uploads the firmware image to the Arduino Uno WiFi over USB with avrdude (Optiboot, 115200 baud).
#   firmware/flash.sh PORT [KEY_HEX_FILE]
# PORT         serial device of the board, e.g. /dev/ttyACM0
# KEY_HEX_FILE optional EEPROM image with the craft's MAC key, made by
#              firmware/tools/provision_key.py (flashed over USB only; the firmware has no way to
#              receive a key over WiFi). Without it the EEPROM is left as it is.
# `make flash PORT=/dev/ttyACM0` builds first (make firmware) and then runs this.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
if [ $# -lt 1 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
  sed -n '2,/^set /p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'; [ $# -ge 1 ] && exit 0 || exit 2
fi
port=$1
hex="$here/.pio/build/uno_wifi/program.hex"
[ -f "$hex" ] || { echo "flash.sh: $hex not built: run 'make firmware'"; exit 1; }
[ -e "$port" ] || { echo "flash.sh: serial port $port does not exist"; exit 1; }
args=(-p atmega328p -c arduino -P "$port" -b 115200 -D -U "flash:w:$hex:i")
if [ $# -ge 2 ]; then
  [ -f "$2" ] || { echo "flash.sh: key file $2 not found"; exit 1; }
  args+=(-U "eeprom:w:$2:i")
fi
exec avrdude "${args[@]}"
