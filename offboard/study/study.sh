#!/usr/bin/env bash
# `make study`: the spatial-velocity study (thesis Chapter 4) on DATA (default ../shared/data, else
#   data/tum: scripts/data-dir.sh).
#   1. sweep: every TUM-layout dataset under DATA x sift/surf/orb x vo/llc/glc x k (slam-study run,
#      resumable: finished runs in OUT/runs are not redone; wall time printed and kept in sweep.json)
#   2. report: OUT/report.md + tables/*.csv + plots/*.png + pairs.csv, with the reference
#      trajectories in DATA/reference_trajectories analysed as peers
#   2b. the guide's shipped table offboard/study/slam_study/data/guide_pairs.csv from the sweep's
#      vo runs (slam-study table; pytest fails while it is stale)
#   2c. with STUDY_RENDERED=DIR (folders rendered by hil/tools/render_tum.py, e.g. out/bench/rendered
#      from make bench): the same sweep of them on their own into OUT-rendered, slam-eval
#      --no-undistort --rolling-shutter off (rendered frames have no lens distortion and a global
#      shutter); a report only: the guide's table rests on recorded sequences (docs/study.md)
#   3. the Ray-cluster test (a private head node on loopback; skip with STUDY_RAY_TEST=0)
# Env: DATA, STUDY_OUT (default build/study), RGBD_BUILD_DIR (default build), STUDY_K (k list),
#      STUDY_JOBS (default: nproc), STUDY_BACKENDS / STUDY_FEATURES (comma lists; the shipped table
#      needs only the vo runs: `STUDY_BACKENDS=vo make study` regenerates it in ~1/3 of the time).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
DATA=${DATA:-$(scripts/data-dir.sh)}
OUT=${STUDY_OUT:-$root/build/study}
export RGBD_BUILD_DIR=${RGBD_BUILD_DIR:-$root/build}
export PYTHONPATH="$root/offboard/study${PYTHONPATH:+:$PYTHONPATH}"
export MPLBACKEND=Agg RAY_USAGE_STATS_ENABLED=0
py=$root/.venv/bin/python
k_args=(); [ -n "${STUDY_K:-}" ] && k_args=(--k "$STUDY_K")
sel_args=()
[ -n "${STUDY_BACKENDS:-}" ] && sel_args+=(--backends "$STUDY_BACKENDS")
[ -n "${STUDY_FEATURES:-}" ] && sel_args+=(--features "$STUDY_FEATURES")

if [ ! -d "$DATA" ]; then echo "study: data directory '$DATA' not found (run make data, or set DATA=...)"; exit 1; fi
refs=()
add_ref() { [ -f "$DATA/reference_trajectories/$2" ] && [ -d "$DATA/$1" ] && refs+=(--reference "$DATA/$1" "$DATA/reference_trajectories/$2"); return 0; }
add_ref fr1_xyz_first300 freiburg1_xyz-rgbdslam.txt
add_ref fr2_desk_first50 fr2_desk_ORB.txt

status=0
if [ -x "$RGBD_BUILD_DIR/bin/slam-eval" ]; then
  # --no-map: the study reads trajectories and metrics only; the PLY map would cost time per run.
  "$py" -m slam_study run --data "$DATA" --out "$OUT" --jobs "${STUDY_JOBS:-$(nproc)}" \
    --slam-eval-args "--no-map --quiet" "${k_args[@]}" "${sel_args[@]}" "${refs[@]}" || status=1
  "$py" -m slam_study table --report "$OUT" || status=1
  if [ -n "${STUDY_RENDERED:-}" ]; then
    "$py" -m slam_study run --data "$STUDY_RENDERED" --out "$OUT-rendered" \
      --jobs "${STUDY_JOBS:-$(nproc)}" \
      --slam-eval-args "--no-map --quiet --no-undistort --rolling-shutter off" \
      "${k_args[@]}" "${sel_args[@]}" || status=1
    echo "study: rendered manoeuvres' report in $OUT-rendered/report.md"
  fi
else
  echo "study: $RGBD_BUILD_DIR/bin/slam-eval not built: no sweep; report from the reference trajectories only"
  "$py" -m slam_study report --out "$OUT" "${k_args[@]}" "${refs[@]}" || status=1
  status=1
fi
echo "study: report in $OUT/report.md"
"$py" -m slam_study guide --trans-vel 0.3 --rot-vel 15 --target-rpe-mm 8 || status=1

if [ "${STUDY_RAY_TEST:-1}" = "1" ]; then
  SLAM_STUDY_RAY_TEST=1 "$py" -m pytest -q offboard/study/slam_study/tests/test_ray.py || status=1
fi
exit $status
