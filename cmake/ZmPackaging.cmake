# Debian packages with CPack (docs/api.md "Debian packages"):
#
#   libzonemap-dev  the `dev` install component: headers, libzonemap.a, the CMake package, zonemap.pc
#   zonemap         the `runtime` component: zonemap, zonemapd, zonemap-cotenant, the profiles, the
#                   systemd unit zonemapd@.service and its per-profile memory drop-ins
#
#   cd build/<preset> && cpack -G DEB       (make package, or `make test-package` which checks them)
#
# Depends of `zonemap`: on a native build dpkg-shlibdeps computes them from the binaries. A cross
# build cannot ask dpkg about the target's libraries (the arm64 sysroot is unpacked .debs without
# a dpkg database), so it uses ZM_DEB_CROSS_DEPENDS, the list dpkg-shlibdeps gives for the same
# binaries built natively on Debian 12 (package names are the same on every architecture of a
# release). scripts/package-test.sh checks it: the arm64 binaries need exactly the shared
# libraries the amd64 ones need, each is in the sysroot, and the list equals the amd64 package's
# computed Depends. Cross-building for another distribution (JetPack's Ubuntu) means setting
# ZM_DEB_CROSS_DEPENDS_OVERRIDE to that distribution's package names, or building natively.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(ZM_DEB_ARCH amd64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64|ARM64)$")
  set(ZM_DEB_ARCH arm64)
else()
  set(ZM_DEB_ARCH ${CMAKE_SYSTEM_PROCESSOR})
endif()

# A plain variable, not a cache entry: a cache entry keeps the value of the first configure, so a
# build tree would package a stale list after this one changes (it did, when libjpeg-turbo came
# in). Another distribution's names go in ZM_DEB_CROSS_DEPENDS_OVERRIDE. features2d since issue 26:
# the tick's front-end (zm_localization_orb, through zm_runtime) extracts ORB, so both programs
# link it. flann is only features2d's own dependency (not NEEDED by our binaries under
# --as-needed), so dpkg-shlibdeps leaves it out on amd64 and this list must too.
set(ZM_DEB_CROSS_DEPENDS
  "libc6 (>= 2.35), libgcc-s1 (>= 3.4), libjpeg62-turbo (>= 1.3.1), libopencv-core406 (>= 4.6.0+dfsg), libopencv-features2d406 (>= 4.6.0+dfsg), libopencv-imgcodecs406 (>= 4.6.0+dfsg), libopencv-imgproc406 (>= 4.6.0+dfsg), libpng16-16 (>= 1.6.2-1), libsqlite3-0 (>= 3.30.1+fossil191229), libstdc++6 (>= 11), libtomlplusplus3 (>= 3.2.0), zlib1g (>= 1:1.2.0)")
set(ZM_DEB_CROSS_DEPENDS_OVERRIDE "" CACHE STRING
  "Depends of the zonemap package on a cross build for another distribution (empty: Debian 12's)")
if(ZM_DEB_CROSS_DEPENDS_OVERRIDE)
  set(ZM_DEB_CROSS_DEPENDS "${ZM_DEB_CROSS_DEPENDS_OVERRIDE}")
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME zonemap)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "zonemap")
set(CPACK_PACKAGE_CONTACT "zonemap dev <dev@zonemap.invalid>")
# No CPACK_PACKAGE_DESCRIPTION_SUMMARY: CPackDeb would prepend it to each component's own
# description, whose first line is that package's synopsis.
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)  # executables only: CMake never strips a static archive's symbols
set(CPACK_PACKAGE_DIRECTORY ${PROJECT_BINARY_DIR}/packages)
set(CPACK_COMPONENTS_ALL runtime dev)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${ZM_DEB_ARCH})
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)

set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME zonemap)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SECTION science)
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
  "zone-managed keyframe map localization for memory-bounded robots
zonemapd keeps a robot's keyframe map within a hard memory budget next to a
large AI model by loading and unloading whole semantic zones from an SQLite
map database. Includes the zonemap command line (simulator, import, zones,
evaluation), the co-tenant stand-in, the device profiles and a systemd unit
(zonemapd@<profile>) with the profile's memory limits.")
if(CMAKE_CROSSCOMPILING)
  set(CPACK_DEBIAN_RUNTIME_PACKAGE_DEPENDS "${ZM_DEB_CROSS_DEPENDS}")
else()
  set(CPACK_DEBIAN_RUNTIME_PACKAGE_SHLIBDEPS ON)
endif()

set(CPACK_DEBIAN_DEV_PACKAGE_NAME libzonemap-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_COMPONENT_DEV_DESCRIPTION
  "zone memory manager library for SLAM systems (development files)
The public C++20 API (zonemap/zonemap.h): drive zonemap's policies with the
host's own keyframe store (ZoneManager), or run zonemap's complete map
database and localization loop (MapLoop). Static library, CMake package
(find_package(zonemap)) and pkg-config file.")
# find_dependency(OpenCV/SQLite3/ZLIB/JPEG/PNG/tomlplusplus) and `pkg-config --static` need their -dev
# packages.
set(ZM_DEB_DEV_DEPENDS
  "libopencv-dev, libsqlite3-dev, zlib1g-dev, libjpeg-dev, libpng-dev, libtomlplusplus-dev")
if(ZM_BUILD_SHARED)
  string(APPEND ZM_DEB_DEV_DEPENDS ", zonemap (= ${PROJECT_VERSION}-1)")
endif()
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "${ZM_DEB_DEV_DEPENDS}")

include(CPack)
