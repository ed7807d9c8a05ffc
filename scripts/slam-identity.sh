#!/usr/bin/env bash
# Byte-for-byte identity of the SLAM engine's deterministic output across a change that must not
# alter behaviour (a restructuring): runs `slam-eval run --mode wait` on every sequence in DATA for
# the default system (ORB local map) and each thesis back-end (vo, llc, glc) with SIFT and ORB,
# and keeps each run's trajectory.tum and trajectory_online.tum.
#
#   scripts/slam-identity.sh record DIR [SLAM_EVAL]   run everything, store the trajectories in DIR
#   scripts/slam-identity.sh compare DIR_A DIR_B      byte-compare two recorded sets; exit 1 on a
#                                                     difference or a run missing from either side
# Record once on the old build (copy its slam-eval aside first), once on the new, then compare.
# Wait mode is deterministic (pipeline.hpp), so any difference is a change of behaviour.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
DATA=${DATA:-$root/../shared/data}

usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }

record() {
  local out=$1 eval_bin=${2:-$root/build/bin/slam-eval}
  [ -x "$eval_bin" ] || { echo "slam-identity: $eval_bin is not built" >&2; exit 2; }
  [ -d "$DATA" ] || { echo "slam-identity: no data folder $DATA" >&2; exit 2; }
  mkdir -p "$out"
  local configs=("orb localmap" "orb vo" "orb llc" "orb glc" "sift vo" "sift llc" "sift glc")
  local seq cfg features backend name n=0
  for seq in "$DATA"/*/; do
    seq=${seq%/}
    [ -f "$seq/rgb.txt" ] || continue
    for cfg in "${configs[@]}"; do
      read -r features backend <<<"$cfg"
      name="$(basename "$seq")-$features-$backend"
      n=$((n + 1))
      echo "slam-identity: [$n] $name" >&2
      if "$eval_bin" run --dataset "$seq" --features "$features" --backend "$backend" \
        --mode wait --no-map --quiet --out "$out/$name" >"$out/$name.log" 2>&1; then
        :
      else
        echo "slam-identity: $name failed (exit $?), see $out/$name.log" >&2
      fi
    done
  done
}

compare() {
  local a=$1 b=$2 same=0 differ=0 name f
  for name in $(cd "$a" && ls -d */ 2>/dev/null | tr -d /) $(cd "$b" && ls -d */ 2>/dev/null | tr -d /); do
    echo "$name"
  done | sort -u >/tmp/slam-identity-names.$$
  while read -r name; do
    for f in trajectory.tum trajectory_online.tum; do
      if [ ! -f "$a/$name/$f" ] || [ ! -f "$b/$name/$f" ]; then
        echo "MISSING $name/$f"; differ=$((differ + 1))
      elif cmp -s "$a/$name/$f" "$b/$name/$f"; then
        same=$((same + 1))
      else
        echo "DIFFER  $name/$f"; differ=$((differ + 1))
      fi
    done
  done </tmp/slam-identity-names.$$
  rm -f /tmp/slam-identity-names.$$
  echo "slam-identity: $same identical, $differ different or missing"
  [ "$differ" -eq 0 ]
}

case "${1:-}" in
  record) [ $# -ge 2 ] || usage; record "$2" "${3:-}" ;;
  compare) [ $# -eq 3 ] || usage; compare "$2" "$3" ;;
  *) usage ;;
esac
