#!/usr/bin/env bash
# `make bench` part for onboard/: codec figures and end-to-end fps of rgbd-streamer's transport
# through a 120 Mbps token-bucket link, on real TUM frames from DATA (default ../shared/data).
# Uses build/ (make bench builds it); BUILD_DIR overrides. Prints markdown tables, asserts nothing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
data=${DATA:-../shared/data}
build=${BUILD_DIR:-build}
bench="$build/bin/rgbd-stream-bench"
if [ ! -x "$bench" ]; then echo "onboard/bench.sh: $bench not built (run make build)"; exit 1; fi
seq_dir="$data/fr1_xyz_first300"
if [ ! -f "$seq_dir/rgb.txt" ]; then
  echo "onboard/bench.sh: $seq_dir not found, falling back to tests/data/fr1_xyz_first30"
  seq_dir=tests/data/fr1_xyz_first30
fi
echo "# rgbd-streamer transport benchmark ($(nproc) cores, $(uname -m)) on $seq_dir"
"$bench" --data "$seq_dir" --link-mbps "${LINK_MBPS:-120}" --fps 30 --seconds "${BENCH_SECONDS:-8}" \
  --codec-frames "${CODEC_FRAMES:-100}"
