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
# RGBD_CROSS_SYSROOT (-D, set by scripts/onboard-arm.sh): the fallback of deps/post/arm-cross.sh,
# the ARM libraries unpacked into a directory of their own instead of installed beside the host's.
# Empty: the multiarch packages, sysroot "/".
set(RGBD_CROSS_SYSROOT "" CACHE PATH "ARM sysroot (deps/post/arm-cross.sh fallback); empty: multiarch packages")
# try_compile projects read this file again in the same process; without the variable they would
# set the pkg-config environment below back to the multiarch paths for the rest of the configure.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES RGBD_CROSS_SYSROOT)
if(RGBD_CROSS_SYSROOT)
  set(CMAKE_SYSROOT ${RGBD_CROSS_SYSROOT})
  set(CMAKE_FIND_ROOT_PATH ${RGBD_CROSS_SYSROOT})
  set(ENV{PKG_CONFIG_SYSROOT_DIR} ${RGBD_CROSS_SYSROOT})
  set(_rgbd_root ${RGBD_CROSS_SYSROOT})
else()
  set(_rgbd_root "")
  # libyaml-cpp-dev cannot be installed for a foreign architecture (not Multi-Arch: same in Debian
  # 12); a sysroot holds it whole and needs no stand-in.
  set(yaml-cpp_DIR ${CMAKE_CURRENT_LIST_DIR}/yaml-cpp CACHE PATH "yaml-cpp for the cross build")
endif()
# Only the target's .pc files (Debian installs them per triplet; /usr/share/pkgconfig is arch-free).
set(ENV{PKG_CONFIG_LIBDIR} ${_rgbd_root}/usr/lib/${RGBD_CROSS_TRIPLET}/pkgconfig:${_rgbd_root}/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")
# "-L /": the dynamic loader and libc both from libc6:<arch> (/lib/ld-linux-*.so, /usr/lib/<triplet>),
# as on the board. qemu -L /usr/<triplet> would take the loader from libc6-<arch>-cross (2.36-8cross1)
# but libc.so.6 from libc6:<arch> (2.36-9+deb12u14, via ld.so.cache); that mismatched pair hangs
# (arm64) or crashes (armhf) in the first pthread_create. The CPU model is the board's, so an
# instruction the board lacks fails the tests instead of passing on qemu's default "max" CPU.
# With a sysroot, loader and libc are both the sysroot's.
set(_rgbd_qemu_root /)
if(RGBD_CROSS_SYSROOT)
  set(_rgbd_qemu_root ${RGBD_CROSS_SYSROOT})
endif()
set(CMAKE_CROSSCOMPILING_EMULATOR ${RGBD_CROSS_QEMU} -cpu ${RGBD_CROSS_QEMU_CPU} -L ${_rgbd_qemu_root})
# For scripts/onboard-arm.sh (runs the ARM rgbd-streamer under the same emulator in the e2e check).
set(RGBD_CROSS_EMULATOR "${CMAKE_CROSSCOMPILING_EMULATOR}" CACHE INTERNAL "emulator command")
