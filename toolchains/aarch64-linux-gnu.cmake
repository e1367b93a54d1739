# Cross-build for 64-bit ARM (the Jetson's ISA) with Debian's aarch64-linux-gnu-g++ against the
# arm64 sysroot that scripts/install-deps.sh unpacks from Debian's arm64 archive (see there why
# it is a sysroot and not multiarch packages). ctest runs the binaries under qemu-user.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

if(NOT ZM_ARM64_SYSROOT)
  if(DEFINED ENV{ZM_ARM64_SYSROOT})
    set(ZM_ARM64_SYSROOT "$ENV{ZM_ARM64_SYSROOT}")
  else()
    set(ZM_ARM64_SYSROOT /opt/zonemap/sysroot-arm64)
  endif()
endif()
set(ZM_ARM64_SYSROOT "${ZM_ARM64_SYSROOT}" CACHE PATH "arm64 root filesystem with the target libraries")
if(NOT EXISTS "${ZM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu")
  message(FATAL_ERROR "arm64 sysroot '${ZM_ARM64_SYSROOT}' is missing: run scripts/install-deps.sh")
endif()
set(CMAKE_SYSROOT "${ZM_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${ZM_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# Transitive shared-library dependencies of OpenCV live in the multiarch directory.
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${ZM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${ZM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${ZM_ARM64_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR} "${ZM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${ZM_ARM64_SYSROOT}/usr/share/pkgconfig")

# Run target binaries (tests, doctest discovery) on the host.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L "${ZM_ARM64_SYSROOT}")
# Generic ARMv8-A: runs on any 64-bit ARM, including the Jetson's Cortex-A78AE.
set(CMAKE_C_FLAGS_INIT "-march=armv8-a")
set(CMAKE_CXX_FLAGS_INIT "-march=armv8-a")
