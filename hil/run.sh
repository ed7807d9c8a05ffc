#!/usr/bin/env bash
# `make hil`: every hardware-in-loop scenario (pytest tests marked `hil` under hil/), then a summary
# of what each reported (test-artifacts/hil/*.json, also written to out/results/hil.json) and the
# latency budget.
#   RGBD_BUILD_DIR   build folder holding bin/fw_sim, bin/slam-eval, ... (default: build)
#   RGBD_FIRMWARE_ELF firmware image (default: firmware/.pio/build/uno_wifi/program.elf)
# A scenario whose components are not built fails with the reason (HIL_STRICT=1; set HIL_STRICT=0
# to let such scenarios skip while running a subset). Extra args go to pytest.
set -uo pipefail
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export RGBD_BUILD_DIR=${RGBD_BUILD_DIR:-$root/build}
export MPLBACKEND=Agg
export HIL_STRICT=${HIL_STRICT:-1}
# The summary tools below run outside pytest (whose pythonpath is in pyproject.toml): the same paths.
export PYTHONPATH=$root/protocol/python:$root/offboard/quadcontrol:$root/offboard/recorder:$root/offboard/study:$root/hil${PYTHONPATH:+:$PYTHONPATH}
rm -f test-artifacts/hil/*.json
.venv/bin/python -m pytest -m hil hil -v -s -rsxX "$@"
status=$?
echo "=== HIL summary (test-artifacts/hil/)"
for f in test-artifacts/hil/*.json; do
  [ -e "$f" ] || continue
  .venv/bin/python - "$f" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print(sys.argv[1].split("/")[-1] + ": " + ", ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}"
                                                    for k, v in d.items() if k != "events"))
PY
done
.venv/bin/python hil/hilrig/latency_budget.py test-artifacts/hil
# Each scenario's figures into out/results/hil.json for docs/results.md (make results).
python3 scripts/results_write.py hil test-artifacts/hil || true
exit $status
