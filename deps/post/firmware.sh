#!/usr/bin/env bash
# Firmware set-up for an OFFLINE PlatformIO build (idempotent; `make deps` runs it):
# PlatformIO normally downloads its build engine (tool-scons) from its own registry, which this
# machine cannot reach. Here it is provided from PyPI's scons (pinned in requirements/firmware.txt,
# installed into .venv) as a core package inside the repo's own PLATFORMIO_CORE_DIR
# (firmware/.pio-core, git-ignored). The AVR platform itself is firmware/pio-platform, referenced
# from platformio.ini with symlink://, and uses Debian's avr-gcc/avr-libc (deps/apt/firmware.txt).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
core="$root/firmware/.pio-core"
pkg="$core/packages/tool-scons"
# PlatformIO 6.2 requires tool-scons "~4.41101.0"; the version label is what it checks.
version="4.41101.0"
mkdir -p "$pkg"
want_manifest="{\"name\": \"tool-scons\", \"version\": \"$version\", \"description\": \"SCons from PyPI (requirements/firmware.txt), for offline PlatformIO builds\"}"
want_meta="{\"type\": \"tool\", \"name\": \"tool-scons\", \"version\": \"$version\", \"spec\": {\"owner\": \"platformio\", \"id\": null, \"name\": \"tool-scons\", \"requirements\": null, \"uri\": null}}"
want_entry='# Entry point PlatformIO runs with the .venv interpreter: the SCons installed from PyPI.
import sys
import SCons.Script
sys.exit(SCons.Script.main())
'
changed=0
[ "$(cat "$pkg/package.json" 2>/dev/null)" = "$want_manifest" ] || { printf '%s' "$want_manifest" > "$pkg/package.json"; changed=1; }
[ "$(cat "$pkg/.piopm" 2>/dev/null)" = "$want_meta" ] || { printf '%s' "$want_meta" > "$pkg/.piopm"; changed=1; }
[ "$(cat "$pkg/scons.py" 2>/dev/null)" = "$(printf '%s' "$want_entry")" ] || { printf '%s' "$want_entry" > "$pkg/scons.py"; changed=1; }
if [ "$changed" -eq 1 ]; then echo "deps/post/firmware.sh: offline tool-scons set up in $pkg"; fi
