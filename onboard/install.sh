#!/usr/bin/env bash
# `make install-onboard`: installs rgbd-streamer on THIS (onboard) machine, idempotently:
#   binary  -> $PREFIX/bin/rgbd-streamer              (PREFIX default /usr/local)
#   config  -> /etc/rgbd-streamer/rgbd-streamer.yaml   (kept if it exists: it holds local settings)
#   unit    -> /etc/systemd/system/rgbd-streamer.service
#   docs    -> $PREFIX/share/doc/rgbd-streamer/README.md
#   user    -> system user 'rgbd' in groups plugdev, video (USB access to the Kinect)
# then enables and (re)starts the service. Options (environment):
#   DESTDIR=/tmp/stage  install into a staging root (no user, no systemctl; for packaging/tests)
#   NO_ENABLE=1         install files and user, do not enable/start the service
#   BUILD_DIR=build     where rgbd-streamer was built (make build)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
prefix=${PREFIX:-/usr/local}
dest=${DESTDIR:-}
binary="$build/bin/rgbd-streamer"
[ -x "$binary" ] || { echo "install-onboard: $binary not found: run 'make build' first"; exit 1; }
sudo_cmd=()
if [ -z "$dest" ] && [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
run() { "${sudo_cmd[@]}" "$@"; }

run install -D -m 0755 "$binary" "$dest$prefix/bin/rgbd-streamer"
if [ -e "$dest/etc/rgbd-streamer/rgbd-streamer.yaml" ]; then
  echo "install-onboard: keeping existing /etc/rgbd-streamer/rgbd-streamer.yaml (new defaults: $root/onboard/config/rgbd-streamer.yaml)"
else
  run install -D -m 0644 "$root/onboard/config/rgbd-streamer.yaml" "$dest/etc/rgbd-streamer/rgbd-streamer.yaml"
fi
sed "s#/usr/local/#$prefix/#g" "$root/onboard/systemd/rgbd-streamer.service" > "${TMPDIR:-/tmp}/rgbd-streamer.service.$$"
run install -D -m 0644 "${TMPDIR:-/tmp}/rgbd-streamer.service.$$" "$dest/etc/systemd/system/rgbd-streamer.service"
rm -f "${TMPDIR:-/tmp}/rgbd-streamer.service.$$"
run install -D -m 0644 "$root/onboard/README.md" "$dest$prefix/share/doc/rgbd-streamer/README.md"

# The binary must start (shared libraries present) and accept the installed config.
"$dest$prefix/bin/rgbd-streamer" --config "$dest/etc/rgbd-streamer/rgbd-streamer.yaml" --print-config > /dev/null

if [ -n "$dest" ]; then
  echo "install-onboard: staged into $dest (no user, no systemctl)"
  exit 0
fi
for group in plugdev video; do getent group "$group" > /dev/null || run groupadd --system "$group"; done
if ! id rgbd > /dev/null 2>&1; then
  run useradd --system --no-create-home --home-dir /nonexistent --shell /usr/sbin/nologin \
    --user-group --groups plugdev,video rgbd
fi
if [ -n "${NO_ENABLE:-}" ]; then
  echo "install-onboard: installed; not enabled (NO_ENABLE set)"
  exit 0
fi
if [ "$(ps -p 1 -o comm= 2>/dev/null)" != "systemd" ]; then
  echo "install-onboard: installed; systemd is not PID 1 here, so the unit was not enabled."
  echo "  On the board: sudo systemctl daemon-reload && sudo systemctl enable --now rgbd-streamer"
  exit 0
fi
run systemctl daemon-reload
run systemctl enable rgbd-streamer.service
run systemctl restart rgbd-streamer.service
echo "install-onboard: rgbd-streamer enabled and started (journalctl -u rgbd-streamer -f)"
