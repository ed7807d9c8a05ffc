#!/usr/bin/env bash
# make run-offboard: the ground station for the real craft.
#
#   quad-control --config $QC_CONFIG   (default ~/.config/rgbdquad/quad-control.json, a copy of
#                                       offboard/quadcontrol/config/quad-control.json with the key set)
# Addresses and ports (from that config; docs/control.md):
#   dashboard     http://127.0.0.1:8080/          (loopback; another bind address needs a token)
#   RGB-D stream  0.0.0.0:5600 (RGB), :5601 (depth) - rgbd-streamer on the craft connects here
#   firmware      http://192.168.240.1:80/control - Arduino Uno WiFi bridge (its own access point)
# SLAM runs inside quad-control (the SLAM engine's front-end); slam-server is started only once
# quad-control can use it (slam.mode "server" is not wired yet), so this script does not start it.
# Stop with Ctrl-C (quad-control stops its threads and exits).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${QUAD_CONTROL_BIN:-$root/build/bin/quad-control}
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
To try the ground station without the craft:  $bin --no-firmware   (replays tests/data/fr1_xyz_first30)
MSG
  exit 1
fi
if [ -x "$root/build/bin/slam-server" ]; then
  echo "run-offboard: slam-server exists but quad-control does not use it yet (slam.mode in-process)"
fi
exec "$bin" --config "$config" "$@"
