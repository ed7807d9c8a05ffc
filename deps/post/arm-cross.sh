#!/usr/bin/env bash
# ARM cross-build set-up (idempotent; `make deps` runs it, so does `make onboard-arm`):
# enables the dpkg architectures in ARM_ARCHES (default "arm64 armhf") and installs Debian's cross
# toolchains, the multiarch -dev packages of deps/arm/packages.txt and qemu-user.
# ARM_DEPS=0 skips it (a machine that never cross-builds; `make test` then reports the ARM step failed).
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

need_update=0
for arch in $arches; do
  if ! dpkg --print-foreign-architectures | grep -qx "$arch"; then
    "${sudo_cmd[@]}" dpkg --add-architecture "$arch"
    need_update=1
  fi
done
missing=()
for pkg in "${wanted[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done
if [ "${#missing[@]}" -eq 0 ] && [ "$need_update" -eq 0 ]; then
  echo "deps/post/arm-cross.sh: all ${#wanted[@]} ARM cross packages present ($arches)"
  exit 0
fi
echo "deps/post/arm-cross.sh: installing ${#missing[@]} package(s) for $arches: ${missing[*]}"
"${sudo_cmd[@]}" apt-get update -q
# No recommends: qemu-user would otherwise pull qemu-user-binfmt (system-wide binfmt registration).
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
