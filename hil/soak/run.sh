#!/usr/bin/env bash
# `make soak`: HIL missions back to back for SOAK_MINUTES (default 60) under the seeded fault
# schedule SOAK_SEED (default in hil/soak/schedule.py), then the report (out/soak/report.{json,txt},
# out/results/soak.json) and the replay check. docs/hil.md, section Soak.
#   RGBD_BUILD_DIR    build folder holding bin/fw_sim, bin/slam-server, ... (default: build)
#   RGBD_FIRMWARE_ELF firmware image (default: firmware/.pio/build/uno_wifi/program.elf)
#   SOAK_OUT          report folder (default: out/soak)
# Extra args go to `python -m soak.runner` (--help lists them). Ctrl-C stops every process it
# started, by PID, and writes the report of the missions flown so far.
set -uo pipefail
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
export RGBD_BUILD_DIR=${RGBD_BUILD_DIR:-$root/build}
export MPLBACKEND=Agg
# The paths pytest uses for the HIL scenarios (pyproject.toml), for a run outside pytest.
export PYTHONPATH=$root/protocol/python:$root/offboard/recorder:$root/onboard/python:$root/hil:$root/firmware/tools${PYTHONPATH:+:$PYTHONPATH}
exec .venv/bin/python -m soak.runner --out "${SOAK_OUT:-$root/out/soak}" "$@"
