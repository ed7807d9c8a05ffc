#!/usr/bin/env bash
# `make demo` (via scripts/demo.sh): HIL scenario 2, a simulated flight with SLAM in the loop
# (hil/demo.py; options: --fps, --hold-s, --linger-s, --out). Needs make build (C++ programs and the
# firmware image) and fakenect (libfreenect-bin); if any is missing, says what and runs the SLAM-only
# demo (offboard/demo.sh) instead.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export RGBD_BUILD_DIR=${RGBD_BUILD_DIR:-$root/build}
export PYTHONPATH="$root/hil:$root/protocol/python:$root/firmware/tools:$root/offboard/python${PYTHONPATH:+:$PYTHONPATH}"
python=.venv/bin/python
[ -x "$python" ] || python=python3
status=0
"$python" hil/demo.py "$@" || status=$?
if [ "$status" = 2 ]; then
  echo "demo: falling back to the SLAM-only demo (offboard/demo.sh)"
  exec offboard/demo.sh
fi
exit "$status"
