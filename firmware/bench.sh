#!/usr/bin/env bash
# Firmware figures (run by `make bench`): image size, and the simavr measurements of the real image
# (pulse-width/period error, failsafe engage time and hand-over step, over-long line replies,
# commands/s with replies, MAVLink ages).
# Needs `make build` (build/bin/fw_sim and the firmware image).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
"$here/build.sh" | grep '^firmware:'
cd "$root"
.venv/bin/python -m pytest -q -s hil/arduino/tests/test_simavr.py 2>&1 | grep -E '^simavr|passed|failed'
