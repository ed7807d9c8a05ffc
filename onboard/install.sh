#!/usr/bin/env bash
# `make install-onboard`: installs rgbd-streamer on THIS (onboard) machine as a Debian package:
#   DEB=<file.deb>  install that package (e.g. built on a PC with `make onboard-arm ARCH=armhf
#                   PACKAGE=1` and copied to the board), else the package is built from BUILD_DIR
#                   (default build/, `make build`) for this machine's architecture (onboard/package-deb.sh).
# apt installs it with its declared dependencies; the package's postinst creates the system user
# 'rgbd' (groups plugdev, video: USB access to the Kinect) and enables + (re)starts the unit when
# systemd runs. Files: /usr/bin/rgbd-streamer, /etc/rgbd-streamer/rgbd-streamer.yaml (a conffile:
# local edits are kept on upgrade), /lib/systemd/system/rgbd-streamer.service,
# /usr/share/doc/rgbd-streamer/README.md. The stream key (/etc/rgbd-streamer/stream.key, mode 0600,
# docs/security.md) is per craft and must be put there by hand.
#   DESTDIR=/tmp/stage  unpack the package into a staging root instead (no apt, no user, no
#                       systemctl; an existing staged config is kept, as dpkg does; for tests)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
dest=${DESTDIR:-}
deb=${DEB:-}
if [ -z "$deb" ]; then
  [ -x "$build/bin/rgbd-streamer" ] || { echo "install-onboard: $build/bin/rgbd-streamer not found: run 'make build' first"; exit 1; }
  "$root/onboard/package-deb.sh" "$build"
  deb=$(ls -t "$build"/rgbd-streamer_*_"$(dpkg --print-architecture)".deb | head -1)
fi
[ -f "$deb" ] || { echo "install-onboard: $deb not found"; exit 1; }

if [ -n "$dest" ]; then
  unpacked=$(mktemp -d)
  trap 'rm -rf "$unpacked"' EXIT
  dpkg-deb -x "$deb" "$unpacked"
  while read -r conffile; do  # keep a staged config like dpkg keeps an edited conffile
    if [ -e "$dest$conffile" ]; then
      echo "install-onboard: keeping existing $conffile (new defaults: $root/onboard/config/rgbd-streamer.yaml)"
      rm "$unpacked$conffile"
    fi
  done < <(dpkg-deb -I "$deb" conffiles)
  mkdir -p "$dest"
  cp -a "$unpacked/." "$dest/"
  # The binary must start (shared libraries present) and accept the installed config.
  if [ "$(dpkg-deb -f "$deb" Architecture)" = "$(dpkg --print-architecture)" ]; then
    "$dest/usr/bin/rgbd-streamer" --config "$dest/etc/rgbd-streamer/rgbd-streamer.yaml" --print-config > /dev/null
  fi
  echo "install-onboard: $(basename "$deb") unpacked into $dest (no user, no systemctl)"
  exit 0
fi
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
case "$deb" in /*) ;; *) deb="./$deb" ;; esac  # apt needs a path to take it as a file
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y --reinstall "$deb"
/usr/bin/rgbd-streamer --config /etc/rgbd-streamer/rgbd-streamer.yaml --print-config > /dev/null
if [ -d /run/systemd/system ]; then
  echo "install-onboard: rgbd-streamer installed, enabled and started (journalctl -u rgbd-streamer -f)"
else
  echo "install-onboard: installed; systemd is not PID 1 here, so the unit was not started."
  echo "  On the board: sudo systemctl enable --now rgbd-streamer"
fi
