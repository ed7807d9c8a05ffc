#!/usr/bin/env bash
# Builds the Debian package of rgbd-streamer from a build directory, with dpkg-deb:
#   onboard/package-deb.sh <build-dir> [<debian-arch>]     (arch default: this machine's)
# -> <build-dir>/rgbd-streamer_<version>_<arch>.deb holding
#   /usr/bin/rgbd-streamer                       (stripped)
#   /etc/rgbd-streamer/rgbd-streamer.yaml        (conffile: dpkg keeps local edits on upgrade)
#   /lib/systemd/system/rgbd-streamer.service    (onboard/systemd, paths /usr/local -> /usr)
#   /usr/share/doc/rgbd-streamer/README.md
# Depends: the Debian packages owning each shared library the binary needs (readelf NEEDED ->
# /usr/lib/<triplet> -> dpkg -S, so the list follows the build, not a hand-kept list) + adduser.
# postinst creates the system user rgbd (groups plugdev, video) and enables/restarts the unit when
# systemd runs; prerm stops and disables it on removal. The stream key (/etc/rgbd-streamer/stream.key,
# docs/security.md) is a secret per craft and is not shipped.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:?usage: onboard/package-deb.sh <build-dir> [<debian-arch>]}
arch=${2:-$(dpkg --print-architecture)}
binary="$build/bin/rgbd-streamer"
[ -x "$binary" ] || { echo "package-deb: $binary not built" >&2; exit 1; }
triplet=$(dpkg-architecture -a"$arch" -qDEB_HOST_MULTIARCH 2>/dev/null)
version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$build/CMakeCache.txt")
[ -n "$version" ] || version=$(sed -n 's/^project(rgbdquad VERSION \([0-9.]*\).*/\1/p' "$root/CMakeLists.txt")
strip_cmd=strip
if [ "$arch" != "$(dpkg --print-architecture)" ]; then strip_cmd=$triplet-strip; fi

stage=$(mktemp -d)
chmod 0755 "$stage"
trap 'rm -rf "$stage"' EXIT
install -D -m 0755 "$binary" "$stage/usr/bin/rgbd-streamer"
"$strip_cmd" --strip-unneeded "$stage/usr/bin/rgbd-streamer"
install -D -m 0644 "$root/onboard/config/rgbd-streamer.yaml" "$stage/etc/rgbd-streamer/rgbd-streamer.yaml"
install -d "$stage/lib/systemd/system"
sed 's#/usr/local/#/usr/#g' "$root/onboard/systemd/rgbd-streamer.service" > "$stage/lib/systemd/system/rgbd-streamer.service"
install -D -m 0644 "$root/onboard/README.md" "$stage/usr/share/doc/rgbd-streamer/README.md"

# RGBD_CROSS_SYSROOT (scripts/onboard-arm.sh, deps/post/arm-cross.sh's fallback): the libraries
# are in that directory, and its .rgbd-file-owners names the package of each file.
sysroot=${RGBD_CROSS_SYSROOT:-}
sysroot_real=""
[ -z "$sysroot" ] || sysroot_real=$(readlink -f "$sysroot")
owner_of() {  # owner_of <path inside the target's file system>
  if [ -n "$sysroot" ]; then
    awk -v f="$1" '$1 == f { print $2; exit }' "$sysroot/.rgbd-file-owners"
  else
    dpkg -S "$1" 2>/dev/null | head -1 | cut -d: -f1 || true
  fi
}
depends=()
for lib in $(readelf -d "$binary" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
  path=""
  for dir in "/usr/lib/$triplet" "/lib/$triplet"; do
    if [ -e "$sysroot$dir/$lib" ]; then
      path=$(cd "$sysroot$dir" && readlink -f "$lib"); path=${path#"$sysroot_real"}; break
    fi
  done
  [ -n "$path" ] || { echo "package-deb: $lib (needed by $binary) not found for $triplet" >&2; exit 1; }
  owner=$(owner_of "$path")
  if [ -z "$owner" ]; then  # dpkg records /lib paths for some packages (usrmerge): try that spelling
    owner=$(owner_of "${path#/usr}")
  fi
  [ -n "$owner" ] || { echo "package-deb: no Debian package owns $path" >&2; exit 1; }
  depends+=("$owner")
done
depends_line=$(printf '%s\n' "${depends[@]}" adduser | sort -u | paste -sd, | sed 's/,/, /g')

mkdir -p "$stage/DEBIAN"
cat > "$stage/DEBIAN/control" <<CONTROL
Package: rgbd-streamer
Version: $version
Architecture: $arch
Maintainer: rgbdquad onboard <onboard@rgbdquad.invalid>
Depends: $depends_line
Section: misc
Priority: optional
Installed-Size: $(du -sk --exclude=DEBIAN "$stage" | cut -f1)
Description: RGB-D streamer for the quadcopter's companion board
 Captures a Kinect v1 (libfreenect), an OpenNI2 device or a TUM RGB-D folder, drops blank and
 malformed frames and streams RGB and depth to the ground station over two authenticated TCP
 streams, reconnecting forever. Runs as the systemd service rgbd-streamer (user rgbd).
CONTROL
echo /etc/rgbd-streamer/rgbd-streamer.yaml > "$stage/DEBIAN/conffiles"
cat > "$stage/DEBIAN/postinst" <<'SCRIPT'
#!/bin/sh
set -e
if [ "$1" = configure ]; then
  for group in plugdev video; do getent group "$group" >/dev/null || addgroup --quiet --system "$group"; done
  getent passwd rgbd >/dev/null || adduser --quiet --system --no-create-home --home /nonexistent --group rgbd
  adduser --quiet rgbd plugdev
  adduser --quiet rgbd video
  if [ -d /run/systemd/system ]; then
    systemctl daemon-reload
    systemctl enable rgbd-streamer.service
    systemctl restart rgbd-streamer.service || true
  fi
fi
SCRIPT
cat > "$stage/DEBIAN/prerm" <<'SCRIPT'
#!/bin/sh
set -e
if [ "$1" = remove ] && [ -d /run/systemd/system ]; then
  systemctl stop rgbd-streamer.service || true
  systemctl disable rgbd-streamer.service || true
fi
SCRIPT
chmod 0755 "$stage/DEBIAN/postinst" "$stage/DEBIAN/prerm"
out="$build/rgbd-streamer_${version}_${arch}.deb"
dpkg-deb --root-owner-group -Zxz --build "$stage" "$out" >/dev/null
echo "package-deb: $out $(stat -c %s "$out") bytes; Depends: $depends_line"
