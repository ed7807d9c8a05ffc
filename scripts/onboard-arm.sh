#!/usr/bin/env bash
# `make onboard-arm ARCH=arm64|armhf`: cross-builds rgbd-streamer and its unit tests for an ARM
# companion board into build-<arch>/ with Debian's cross toolchain (cmake/toolchains/debian-<arch>.cmake;
# packages from deps/arm/packages.txt, installed idempotently by deps/post/arm-cross.sh).
#   scripts/onboard-arm.sh <arm64|armhf> [--test] [--package]
#   --test     the unit tests under qemu-user (ctest runs them through the toolchain's emulator) and
#              the end-to-end check: the ARM rgbd-streamer under qemu streams tests/data to the x86
#              receiver (build/, made by `make build`), frames bit-exact (tests/crosstest/)
#   --package  build-<arch>/rgbd-streamer_<version>_<arch>.deb (onboard/package-deb.sh)
# Offboard, HIL and native firmware tests are not part of the ARM build (they run on the ground station).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
arch=${1:-}
case "$arch" in
  arm64|armhf) ;;
  *) echo "usage: scripts/onboard-arm.sh <arm64|armhf> [--test] [--package]" >&2; exit 2 ;;
esac
shift
do_test=0 do_package=0
for opt in "$@"; do
  case "$opt" in
    --test) do_test=1 ;;
    --package) do_package=1 ;;
    *) echo "onboard-arm: unknown option $opt" >&2; exit 2 ;;
  esac
done
jobs=${JOBS:-$(nproc)}
build=build-$arch

ARM_ARCHES=$arch bash deps/post/arm-cross.sh
# deps/post/arm-cross.sh's fallback: the ARM libraries in a sysroot of their own (present only then).
sysroot=""
if [ -e "build-sysroot-$arch/.rgbd-sysroot" ]; then
  sysroot="$root/build-sysroot-$arch"
  echo "onboard-arm: ARM libraries from the sysroot $sysroot (apt could not install them as multiarch packages)"
fi
export RGBD_CROSS_SYSROOT=$sysroot  # onboard/package-deb.sh looks the libraries up there
# Release at the host build's optimisation level (-O2) without debug info: the package ships the
# binary stripped, and compiling without -g is faster.
cmake -S . -B "$build" -G Ninja -DCMAKE_TOOLCHAIN_FILE="$root/cmake/toolchains/debian-$arch.cmake" \
  -DRGBD_CROSS_SYSROOT="$sysroot" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O2 -DNDEBUG" -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" \
  -DRGBD_BUILD_OFFBOARD=OFF -DRGBD_BUILD_HIL=OFF -DRGBD_BUILD_FIRMWARE_NATIVE=OFF >/dev/null
# The streamer and the unit tests of what runs on the board (protocol_tests replays the golden and
# hostile vectors of protocol/vectors). Not built for ARM: ground-station-side tools and tests
# (rgbd-protocol-tool/-bench, the control-link client codec), and encodings_test, which needs OpenCV
# (not installable for ARM, deps/arm/packages.txt): the codecs are checked on ARM by
# stream_sender_test (PayloadEncoder) and bit for bit by the end-to-end check below.
targets=(rgbd-streamer rgbd-codec-cost protocol_tests capture_test openni2_source_test net_test
         stream_sender_test streamer_config_test)
cmake --build "$build" -j "$jobs" --target "${targets[@]}"
echo "onboard-arm: $build/bin/rgbd-streamer: $(file -b "$build/bin/rgbd-streamer" | cut -d, -f1-2)"

status=0
if [ "$do_test" = 1 ]; then
  echo "=== onboard-arm $arch: unit tests under qemu"
  ctest --test-dir "$build" --output-on-failure -j "$jobs" -E '_NOT_BUILT$' || status=1
  echo "=== onboard-arm $arch: end to end, ARM rgbd-streamer under qemu -> x86 receiver"
  e2e=build/bin/cross_stream_e2e_test
  if [ ! -x "$e2e" ]; then
    echo "onboard-arm: $e2e not built (make build)"; status=1
  else
    # The emulator command of the toolchain file, then the binary.
    emulator=$(sed -n 's/^RGBD_CROSS_EMULATOR:INTERNAL=//p' "$build/CMakeCache.txt" | tr ';' ' ')
    RGBD_STREAMER_CMD="$emulator $root/$build/bin/rgbd-streamer" "$e2e" || status=1
  fi
fi
if [ "$do_package" = 1 ]; then
  onboard/package-deb.sh "$build" "$arch" || status=1
fi
exit $status
