# Build the binary that runs on an NVIDIA Jetson Orin Nano (6x Cortex-A78AE, JetPack 6 =
# Ubuntu 22.04 aarch64). Point JETSON_SYSROOT at a JetPack root filesystem, for example the
# Linux_for_Tegra/rootfs of the L4T BSP, or a copy of the device's / taken with rsync, that has
# the -dev packages of OpenCV, SQLite, Eigen and zlib installed. See the README.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

if(NOT JETSON_SYSROOT AND DEFINED ENV{JETSON_SYSROOT})
  set(JETSON_SYSROOT "$ENV{JETSON_SYSROOT}")
endif()
set(JETSON_SYSROOT "${JETSON_SYSROOT}" CACHE PATH "JetPack root filesystem")
if(NOT JETSON_SYSROOT OR NOT EXISTS "${JETSON_SYSROOT}/usr/lib/aarch64-linux-gnu")
  message(FATAL_ERROR "Set JETSON_SYSROOT to a JetPack root filesystem (got '${JETSON_SYSROOT}')")
endif()
set(CMAKE_SYSROOT "${JETSON_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${JETSON_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${JETSON_SYSROOT}/usr/lib/aarch64-linux-gnu")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${JETSON_SYSROOT}/usr/lib/aarch64-linux-gnu")
# Tune for the Orin's cores; the NEON kernels are selected by ZmSimd.cmake.
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-a78ae")
set(CMAKE_CXX_FLAGS_INIT "-mcpu=cortex-a78ae")
# Without a device at hand, tests of this build can still run under qemu.
find_program(ZM_QEMU_AARCH64 qemu-aarch64)
if(ZM_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${ZM_QEMU_AARCH64}" -L "${JETSON_SYSROOT}")
endif()
