# 32-bit ARM hard-float (the thesis' Pandaboard: dual Cortex-A9, Debian armhf).
# Debian's armhf baseline (ARMv7-A, Thumb-2, VFPv3-D16, no NEON requirement) is kept so the package
# runs on any armhf board; libjpeg-turbo picks its NEON code at run time where the CPU has it.
# Tests run on qemu's Cortex-A9 model.
set(RGBD_CROSS_TRIPLET arm-linux-gnueabihf)
set(RGBD_CROSS_PROCESSOR armv7l)
set(RGBD_CROSS_QEMU qemu-arm)
set(RGBD_CROSS_QEMU_CPU cortex-a9)
# g++ notes that the argument-passing ABI of some std::variant/vector members changed in GCC 7.1
# (-Wpsabi); everything here is built by one compiler, so the note does not apply.
set(CMAKE_CXX_FLAGS_INIT -Wno-psabi)
include(${CMAKE_CURRENT_LIST_DIR}/debian-multiarch.cmake)
