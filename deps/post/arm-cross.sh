#!/usr/bin/env bash
# ARM cross-build set-up (idempotent; `make deps` runs it, so does `make onboard-arm`):
# enables the dpkg architectures in ARM_ARCHES (default "arm64 armhf") and installs Debian's cross
# toolchains, the multiarch -dev packages of deps/arm/packages.txt and qemu-user.
# ARM_DEPS=0 skips it (a machine that never cross-builds; `make test` then reports the ARM step failed).
#
# Fallback, a sysroot: Multi-Arch: same packages must have one version on every architecture. When
# apt cannot satisfy that (seen once: the mirror's bookworm-security armhf index failed its
# checksum, so apt dropped that repository's indexes and offered the ARM libraries only at the
# bookworm versions while the host's libzstd1, libpng16-16, zlib1g came from security), the ARM
# -dev packages are instead unpacked with their dependencies into build-sysroot-<arch>/ by
# mmdebstrap (--variant=extract: nothing installed, no maintainer scripts, no root dpkg database
# touched), from bookworm and bookworm-updates. cmake/toolchains/debian-multiarch.cmake builds
# against it when scripts/onboard-arm.sh passes RGBD_CROSS_SYSROOT (it does when the directory
# holds a complete sysroot). The directory exists only while the fallback is in use: a later run
# that installs the multiarch packages removes it.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
[ "${ARM_DEPS:-1}" = 0 ] && { echo "deps/post/arm-cross.sh: skipped (ARM_DEPS=0)"; exit 0; }
arches=${ARM_ARCHES:-arm64 armhf}
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi

mapfile -t templates < <(sed -e 's/#.*//' -e '/^[[:space:]]*$/d' "$root/deps/arm/packages.txt" | tr -d ' \t')
wanted=()
for arch in $arches; do
  for t in "${templates[@]}"; do wanted+=("${t//@/$arch}"); done
done
mapfile -t wanted < <(printf '%s\n' "${wanted[@]}" | sort -u)

installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
triplet_of() { dpkg-architecture -a"$1" -qDEB_HOST_MULTIARCH 2>/dev/null; }
# OpenNI2 chdir()s into its driver directory, /usr/lib/<triplet>/OpenNI2/Drivers, and dlopen()s the
# drivers by file name. qemu-user maps the guest's absolute paths into the sysroot (-L) for open and
# stat but not for chdir, so with a sysroot the host needs that directory: a symbolic link into the
# sysroot (the last checkout to set up its sysroot owns it; every sysroot holds the same packages).
# Debian 12's armhf libOpenNI2 cannot be pointed elsewhere: it reads only 17 characters of
# OpenNI.ini's Repository. The link is removed before the multiarch packages are installed.
openni_link() { echo "/usr/lib/$(triplet_of "$1")/OpenNI2"; }
link_openni_drivers() {  # link_openni_drivers <arch> <sysroot>
  local link
  link=$(openni_link "$1")
  [ -L "$link" ] || [ ! -e "$link" ] || return 0  # a real directory: libopenni2-0:<arch> installed
  "${sudo_cmd[@]}" mkdir -p "$(dirname "$link")"
  "${sudo_cmd[@]}" ln -sfn "$2/usr/lib/$(triplet_of "$1")/OpenNI2" "$link"
}
drop_openni_links() {
  for arch in $arches; do
    if [ -L "$(openni_link "$arch")" ]; then "${sudo_cmd[@]}" rm -f "$(openni_link "$arch")"; fi
  done
}
drop_sysroots() {
  for arch in $arches; do rm -rf "$root/build-sysroot-$arch"; done
  drop_openni_links
}

need_update=0
for arch in $arches; do
  if ! dpkg --print-foreign-architectures | grep -qx "$arch"; then
    "${sudo_cmd[@]}" dpkg --add-architecture "$arch"
    need_update=1
  fi
done
missing=()
for pkg in "${wanted[@]}"; do installed "$pkg" || missing+=("$pkg"); done
if [ "${#missing[@]}" -eq 0 ] && [ "$need_update" -eq 0 ]; then
  drop_sysroots
  echo "deps/post/arm-cross.sh: all ${#wanted[@]} ARM cross packages present ($arches)"
  exit 0
fi

# The sysroot fallback already in place for every architecture (same package list): nothing to do.
list_hash=$(cat "$root/deps/arm/packages.txt" "$0" | sha256sum | cut -d' ' -f1)
all_sysroots=1
for arch in $arches; do
  [ "$(cat "$root/build-sysroot-$arch/.rgbd-sysroot" 2>/dev/null)" = "$list_hash" ] || all_sysroots=0
done
host_tools=()
for t in "${templates[@]}"; do [[ "$t" == *:@ ]] || host_tools+=("$t"); done
host_missing=()
for arch in $arches; do
  for t in "${host_tools[@]}"; do installed "${t//@/$arch}" || host_missing+=("${t//@/$arch}"); done
done
if [ "$all_sysroots" = 1 ] && [ "${#host_missing[@]}" -eq 0 ]; then
  for arch in $arches; do link_openni_drivers "$arch" "$root/build-sysroot-$arch"; done
  echo "deps/post/arm-cross.sh: cross toolchains present, ARM libraries from build-sysroot-{${arches// /,}} (apt could not install them as multiarch packages)"
  exit 0
fi

echo "deps/post/arm-cross.sh: installing ${#missing[@]} package(s) for $arches: ${missing[*]}"
"$root/scripts/apt-update.sh"
drop_openni_links
# No recommends: qemu-user would otherwise pull qemu-user-binfmt (system-wide binfmt registration).
if DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"; then
  drop_sysroots
  exit 0
fi

echo "deps/post/arm-cross.sh: apt cannot install the ARM libraries as multiarch packages (above);" \
     "unpacking them into build-sysroot-<arch>/ instead"
to_install=("${host_missing[@]}")
installed mmdebstrap || to_install+=(mmdebstrap)
if [ "${#to_install[@]}" -gt 0 ]; then
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${to_install[@]}"
fi
# The sysroot's own C library and C++ runtime (the loader qemu runs is the sysroot's, so libc, ld.so
# and libstdc++ come from one place), libyaml-cpp-dev, which a sysroot can hold whole, and the
# header-only packages the ARM build finds through CMake (the host's copies are outside the sysroot).
sysroot_pkgs=(libc6-dev libstdc++-12-dev libyaml-cpp-dev nlohmann-json3-dev libcli11-dev)
for t in "${templates[@]}"; do
  [[ "$t" == *:@ ]] || continue
  name=${t%:@}
  [ "$name" = libyaml-cpp0.7 ] || sysroot_pkgs+=("$name")
done
mirror=${ARM_SYSROOT_MIRROR:-http://deb.debian.org/debian}
for arch in $arches; do
  dir="$root/build-sysroot-$arch"
  if [ "$(cat "$dir/.rgbd-sysroot" 2>/dev/null)" = "$list_hash" ]; then
    link_openni_drivers "$arch" "$dir"
    continue
  fi
  rm -rf "$dir"
  echo "deps/post/arm-cross.sh: mmdebstrap $arch sysroot -> $dir"
  mmdebstrap --quiet --variant=extract --architectures="$arch" --skip=cleanup/apt/cache \
    --include="$(IFS=,; echo "${sysroot_pkgs[*]}")" bookworm "$dir" \
    "deb $mirror bookworm main" "deb $mirror bookworm-updates main"
  # Which package owns each file (onboard/package-deb.sh names a .deb's dependencies from it; the
  # extract variant keeps no dpkg database).
  for deb in "$dir"/var/cache/apt/archives/*.deb; do
    pkg=$(dpkg-deb -f "$deb" Package)
    dpkg-deb -c "$deb" | awk -v p="$pkg" '{ f = $6; sub(/^\./, "", f); print f, p }'
  done > "$dir/.rgbd-file-owners"
  link_openni_drivers "$arch" "$dir"
  echo "$list_hash" > "$dir/.rgbd-sysroot"
done
