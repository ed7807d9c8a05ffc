#!/usr/bin/env bash
# `make demo` (via scripts/demo.sh): HIL scenario 2, a simulated flight with SLAM in the loop
# (hil/demo.py; options: --fps, --hold-s, --linger-s, --out). Needs make build (C++ programs and the
# firmware image) and fakenect (libfreenect-bin); if any is missing, says what, runs the SLAM-only
# demo (offboard/eval/demo.sh) instead and exits 3 (a miss: no flight was demonstrated).
# Exit status: 0 all targets met, 1 a target missed, 3 the flight could not run (SLAM-only demo ran).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export RGBD_BUILD_DIR=${RGBD_BUILD_DIR:-$root/build}
export PYTHONPATH="$root/hil:$root/protocol/python:$root/firmware/tools:$root/offboard/quadcontrol:$root/offboard/recorder:$root/offboard/study${PYTHONPATH:+:$PYTHONPATH}"
python=.venv/bin/python
[ -x "$python" ] || python=python3
status=0
"$python" hil/demo.py "$@" || status=$?
if [ "$status" = 2 ]; then
  # The closed-loop flight is what `make demo` demonstrates: running the SLAM-only demo instead is
  # shown (it still proves the SLAM on real frames) but counted as a miss, so the exit status never
  # reports a flight that did not happen as a success.
  echo "demo: the closed-loop flight could not run (see above); running the SLAM-only demo instead (offboard/eval/demo.sh)"
  offboard/eval/demo.sh || exit $?
  echo "demo: MISSED: the closed-loop flight did not run (only the SLAM-only demo did); exit status 3"
  exit 3
fi
exit "$status"
