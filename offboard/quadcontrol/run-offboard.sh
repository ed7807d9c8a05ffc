#!/usr/bin/env bash
# make run-offboard: the ground station for the real craft.
#
#   slam-server --bind 127.0.0.1 --port 5700 --checkpoint-dir $SLAM_CHECKPOINT_DIR
#                                                  (if built; SLAM as a separate process; default
#                                                  ~/.local/state/rgbdquad/slam-checkpoints: a
#                                                  slam-server started again during a flight resumes
#                                                  its map and world frame from there)
#   quad-control --config $QC_CONFIG               (default ~/.config/rgbdquad/quad-control.json, a copy
#                                                   of offboard/quadcontrol/config/quad-control.json with
#                                                   firmware.key_hex set)
# Addresses and ports (from that config; docs/control.md):
#   dashboard     http://127.0.0.1:8080/          (loopback; another bind address needs a token)
#   RGB-D stream  stream.bind_address:5600 (RGB), :5601 (depth) - rgbd-streamer on the craft connects
#                 here (this machine's WiFi address, the streamer's `host`; built-in default 127.0.0.1)
#   SLAM link     127.0.0.1:5700                   - slam-server (SLAM_SERVER_ARGS adds options)
#   firmware      http://192.168.240.1:80/control - Arduino Uno WiFi bridge (its own access point)
# Without slam-server, set slam.mode to "in-process" in the config. Stop with Ctrl-C: quad-control
# exits, then slam-server is stopped by its PID.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${QUAD_CONTROL_BIN:-$root/build/bin/quad-control}
slam_bin=${SLAM_SERVER:-$root/build/bin/slam-server}
checkpoints=${SLAM_CHECKPOINT_DIR:-$HOME/.local/state/rgbdquad/slam-checkpoints}
config=${QC_CONFIG:-$HOME/.config/rgbdquad/quad-control.json}
template=$root/offboard/quadcontrol/config/quad-control.json

if [ ! -x "$bin" ]; then
  echo "run-offboard: $bin not built (run make build)" >&2
  exit 1
fi
if [ ! -f "$config" ]; then
  cat >&2 <<MSG
run-offboard: no configuration at $config
  mkdir -p "$(dirname "$config")" && cp "$template" "$config"
  then set firmware.key_hex to the craft's key (the one provisioned over USB, see docs/firmware.md)
  and check the addresses; or point QC_CONFIG at another file.
To try the ground station without the craft:  $bin --no-firmware --slam in-process
  (replays tests/data/fr1_xyz_first30, dashboard on http://127.0.0.1:8080/)
MSG
  exit 1
fi
"$bin" --config "$config" --print-config >/dev/null  # refuse a bad config before starting anything

slam_pid=""
cleanup() { if [ -n "$slam_pid" ]; then kill "$slam_pid" 2>/dev/null || true; wait "$slam_pid" 2>/dev/null || true; fi; }
trap cleanup EXIT
if [ -x "$slam_bin" ]; then
  # shellcheck disable=SC2086
  "$slam_bin" --bind 127.0.0.1 --port 5700 --checkpoint-dir "$checkpoints" ${SLAM_SERVER_ARGS:-} &
  slam_pid=$!
  echo "run-offboard: slam-server pid $slam_pid on 127.0.0.1:5700"
else
  echo "run-offboard: $slam_bin not built; quad-control shows frames but gets no poses unless slam.mode is in-process"
fi
"$bin" --config "$config" "$@" &
qc_pid=$!
# Ctrl-C / SIGTERM: stop quad-control by its PID; the EXIT trap then stops slam-server.
trap 'kill -TERM "$qc_pid" 2>/dev/null || true' INT TERM
status=0
wait "$qc_pid" || status=$?
if kill -0 "$qc_pid" 2>/dev/null; then wait "$qc_pid" || status=$?; fi
exit "$status"
