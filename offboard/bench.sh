#!/usr/bin/env bash
# `make bench` (via scripts/bench.sh): SLAM accuracy and speed on the shared TUM sequences.
#   For fr1_xyz_first300, fr2_desk_first50, fr1_desk_9frames: slam-eval (wait mode) for
#   SIFT/SURF/ORB x VO/LLC/GLC, plus cv::rgbd::RgbdOdometry (rgbd-odometry-peer) on the same frames;
#   then a real-time ORB replay at 30 fps counting dropped front-end frames. Prints tables shaped
#   like thesis Tables 4.8 (RPE) and 4.10 (ATE) and per-stage median ms.
# Env: DATA (default ../shared/data), SLAM_BIN (default build/bin), BENCH_OUT (default out/bench),
#      BENCH_SEQUENCES (space-separated subset), BENCH_DETECTORS, BENCH_BACKENDS.
# OpenCV runs single-threaded (--cv-threads 1) so the *_cpu timings are complete; the two pipeline
# threads still overlap. Takes ~10-20 min on 2 cores.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
DATA=${DATA:-../shared/data}
BIN=${SLAM_BIN:-build/bin}
OUT=${BENCH_OUT:-out/bench}
SEQS=${BENCH_SEQUENCES:-fr1_xyz_first300 fr2_desk_first50 fr1_desk_9frames}
DETS=${BENCH_DETECTORS:-sift surf orb}
BACKS=${BENCH_BACKENDS:-vo llc glc}
for tool in slam-eval rgbd-odometry-peer; do
  [ -x "$BIN/$tool" ] || { echo "bench: $BIN/$tool not built (run make build, or set SLAM_BIN)"; exit 1; }
done
[ -d "$DATA" ] || { echo "bench: DATA directory '$DATA' not found"; exit 1; }
mkdir -p "$OUT"
status=0
start=$(date +%s)
for seq in $SEQS; do
  if [ ! -d "$DATA/$seq" ]; then echo "bench: skipping $seq (not in $DATA)"; continue; fi
  camera=fr1; case "$seq" in fr2*) camera=fr2;; fr3*) camera=fr3;; esac
  mkdir -p "$OUT/$seq"
  for det in $DETS; do
    for back in $BACKS; do
      dir="$OUT/$seq/${det}_${back}"
      echo "bench: [$(( $(date +%s) - start ))s] $seq $det $back"
      if ! "$BIN/slam-eval" run --dataset "$DATA/$seq" --camera "$camera" --features "$det" \
           --backend "$back" --mode wait --cv-threads 1 --no-map --quiet --out "$dir" 2> "$dir.log"; then
        echo "bench:   failed: $(tail -1 "$dir.log")"
        rm -f "$dir/metrics.json"
        [ "$det" = surf ] || status=1
      fi
    done
  done
  echo "bench: [$(( $(date +%s) - start ))s] $seq peer cv::rgbd::RgbdOdometry"
  "$BIN/rgbd-odometry-peer" --dataset "$DATA/$seq" --camera "$camera" --out "$OUT/$seq/peer" \
    2> "$OUT/$seq/peer.log" || { echo "bench:   peer failed"; status=1; }
done
if [ -d "$DATA/fr1_xyz_first300" ]; then
  echo "bench: [$(( $(date +%s) - start ))s] real-time ORB replay at 30 fps"
  "$BIN/slam-eval" run --dataset "$DATA/fr1_xyz_first300" --features orb --backend glc --mode realtime \
    --no-map --quiet --out "$OUT/realtime_orb" 2> "$OUT/realtime_orb.log" || status=1
fi
python3 offboard/tools/bench_table.py "$OUT"
echo "bench: done in $(( $(date +%s) - start )) s; metrics under $OUT/"
exit $status
