#!/usr/bin/env bash
# Runs every component benchmark that exists (offboard/bench/bench.sh, onboard/bench.sh, firmware/bench.sh)
# on DATA (default ../shared/data, else data/tum: scripts/data-dir.sh) and prints their tables; the
# SLAM headline figures (ATE per sequence and mode, frames dropped) go to out/results/bench.json
# for docs/results.md (make results).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export DATA=${DATA:-$(scripts/data-dir.sh)}
if [ ! -d "$DATA" ]; then echo "bench: data directory '$DATA' not found (run make data, or set DATA=...)"; exit 1; fi
ran=0; status=0
for b in offboard/bench/bench.sh onboard/bench.sh firmware/bench.sh; do
  if [ -x "$b" ]; then ran=1; echo "=== $b"; "$b" || status=1; fi
done
[ "$ran" -eq 1 ] || { echo "bench: no benchmarks implemented yet"; exit 1; }
if [ -d "${BENCH_OUT:-out/bench}" ]; then
  python3 scripts/results_write.py bench "${BENCH_OUT:-out/bench}" || status=1
fi
exit $status
