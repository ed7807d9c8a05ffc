# Shared part of the Debian multiarch cross toolchains (debian-arm64.cmake, debian-armhf.cmake):
# Debian's crossbuild-essential-<arch> compilers, the <arch> -dev packages installed beside the
# host's (sysroot "/", libraries in /usr/lib/<triplet>), pkg-config restricted to that triplet, and
# qemu-user as the emulator, so gtest_discover_tests and ctest run the ARM test binaries through it
# (no binfmt registration). Packages: deps/arm/packages.txt (deps/post/arm-cross.sh).
# The including file sets RGBD_CROSS_TRIPLET, RGBD_CROSS_PROCESSOR, RGBD_CROSS_QEMU, RGBD_CROSS_QEMU_CPU.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR ${RGBD_CROSS_PROCESSOR})
set(CMAKE_C_COMPILER ${RGBD_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${RGBD_CROSS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${RGBD_CROSS_TRIPLET})
# Programs (code generators, python) from the host; libraries and headers only for the target.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# Only the target's .pc files (Debian installs them per triplet; /usr/share/pkgconfig is arch-free).
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/${RGBD_CROSS_TRIPLET}/pkgconfig:/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")
# libyaml-cpp-dev cannot be installed for a foreign architecture (not Multi-Arch: same in Debian 12).
set(yaml-cpp_DIR ${CMAKE_CURRENT_LIST_DIR}/yaml-cpp CACHE PATH "yaml-cpp for the cross build")
# "-L /": the dynamic loader and libc both from libc6:<arch> (/lib/ld-linux-*.so, /usr/lib/<triplet>),
# as on the board. qemu -L /usr/<triplet> would take the loader from libc6-<arch>-cross (2.36-8cross1)
# but libc.so.6 from libc6:<arch> (2.36-9+deb12u14, via ld.so.cache); that mismatched pair hangs
# (arm64) or crashes (armhf) in the first pthread_create. The CPU model is the board's, so an
# instruction the board lacks fails the tests instead of passing on qemu's default "max" CPU.
set(CMAKE_CROSSCOMPILING_EMULATOR ${RGBD_CROSS_QEMU} -cpu ${RGBD_CROSS_QEMU_CPU} -L /)
# For scripts/onboard-arm.sh (runs the ARM rgbd-streamer under the same emulator in the e2e check).
set(RGBD_CROSS_EMULATOR "${CMAKE_CROSSCOMPILING_EMULATOR}" CACHE INTERNAL "emulator command")
