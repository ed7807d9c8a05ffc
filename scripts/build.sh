#!/usr/bin/env bash
# Builds: build/ (everything host-side, RelWithDebInfo), build-asan/ (protocol library + tests under
# ASan/UBSan), build-fuzz/ (libFuzzer targets, clang), and the firmware image when firmware/ exists.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
jobs=${JOBS:-$(nproc)}

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "$jobs"

cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DRGBD_SANITIZE=ON \
  -DRGBD_BUILD_ONBOARD=OFF -DRGBD_BUILD_OFFBOARD=OFF -DRGBD_BUILD_HIL=OFF >/dev/null
cmake --build build-asan -j "$jobs"

cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRGBD_FUZZ=ON \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DRGBD_BUILD_ONBOARD=OFF -DRGBD_BUILD_OFFBOARD=OFF \
  -DRGBD_BUILD_HIL=OFF >/dev/null
cmake --build build-fuzz -j "$jobs"

if [ -x firmware/build.sh ]; then
  firmware/build.sh
fi
