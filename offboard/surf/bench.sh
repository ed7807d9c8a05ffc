#!/usr/bin/env bash
# SURF benchmark on DATA (default ../shared/data): speed on four 640x480 frames, invariance under
# rotation/scale and matches against the fr1/xyz ground-truth motion, next to OpenCV SIFT.
# Usage: offboard/surf/bench.sh [BUILD_DIR]   (default build/)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
data=${DATA:-$root/../shared/data}
bench="$build/bin/surf-bench"
[ -x "$bench" ] || { echo "surf bench: $bench not built (make build)"; exit 1; }
xyz="$data/fr1_xyz_first300"
[ -d "$xyz" ] || { echo "surf bench: $xyz not found (set DATA=...)"; exit 1; }
frames=("$xyz/rgb/1305031102.175304.png" "$xyz/rgb/1305031107.143260.png"
        "$(ls "$data"/fr1_desk_9frames/rgb/*.png | head -1)"
        "$(ls "$data"/fr2_desk_first50/rgb/*.png | head -1)")
"$bench" --repeats 5 --sequence "$xyz" "${frames[@]}"
