# 64-bit ARM (Raspberry Pi 3/4/5 and similar companion boards running Debian arm64).
# Debian's arm64 baseline (ARMv8-A) is kept so the package runs on any arm64 board; tests run on
# qemu's Cortex-A72 model (Raspberry Pi 4).
set(RGBD_CROSS_TRIPLET aarch64-linux-gnu)
set(RGBD_CROSS_PROCESSOR aarch64)
set(RGBD_CROSS_QEMU qemu-aarch64)
set(RGBD_CROSS_QEMU_CPU cortex-a72)
include(${CMAKE_CURRENT_LIST_DIR}/debian-multiarch.cmake)
