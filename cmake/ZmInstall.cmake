# Install rules and the exported CMake package (docs/api.md "Install and find").
#
#   cmake --install build/<preset> --prefix PREFIX [--component dev|runtime]
#
# component dev      include/zonemap/*.h, libzonemap.a (or .so + namelink with ZM_BUILD_SHARED),
#                    the CMake package (find_package(zonemap) -> zonemap::zonemap) and zonemap.pc
# component runtime  bin/zonemap, zonemapd, zonemap-cotenant, share/zonemap/profiles/*.toml, the
#                    systemd unit template and per-profile drop-ins (lib/systemd/system), the
#                    environment file example, README
# The Debian packages (cmake/ZmPackaging.cmake) are exactly these two components.
include(CMakePackageConfigHelpers)

# Headers: the public ones only (the core's headers stay private to the build).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/zonemap DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        COMPONENT dev FILES_MATCHING PATTERN "*.h")
install(TARGETS zonemap_lib EXPORT zonemapTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime NAMELINK_COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

set(ZM_CMAKE_PACKAGE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/zonemap)
install(EXPORT zonemapTargets NAMESPACE zonemap:: DESTINATION ${ZM_CMAKE_PACKAGE_DIR}
        COMPONENT dev)
set(ZM_PACKAGE_STATIC ON)
if(ZM_BUILD_SHARED)
  set(ZM_PACKAGE_STATIC OFF)
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/zonemapConfig.cmake.in
  ${PROJECT_BINARY_DIR}/zonemapConfig.cmake INSTALL_DESTINATION ${ZM_CMAKE_PACKAGE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/zonemapConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/zonemapConfig.cmake ${PROJECT_BINARY_DIR}/zonemapConfigVersion.cmake
        DESTINATION ${ZM_CMAKE_PACKAGE_DIR} COMPONENT dev)

# pkg-config: prefix relative to the .pc file, so an unpacked or relocated tree works as is.
file(RELATIVE_PATH ZM_PC_TO_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
set(ZM_PC_PREFIX "\${pcfiledir}/${ZM_PC_TO_PREFIX}")
string(REGEX REPLACE "/$" "" ZM_PC_PREFIX "${ZM_PC_PREFIX}")
# What the library's objects call: `pkg-config --static --libs zonemap` adds them, as the default
# static library needs (docs/api.md); a shared libzonemap carries them itself.
set(ZM_PC_REQUIRES_PRIVATE "opencv4 sqlite3 zlib libjpeg libpng tomlplusplus")
configure_file(${PROJECT_SOURCE_DIR}/cmake/zonemap.pc.in ${PROJECT_BINARY_DIR}/zonemap.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/zonemap.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT dev)

# The programs and what they read.
install(TARGETS zonemap zonemapd zonemap-cotenant RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        COMPONENT runtime)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/profiles/ DESTINATION ${CMAKE_INSTALL_DATADIR}/zonemap/profiles
        COMPONENT runtime FILES_MATCHING PATTERN "*.toml")
install(FILES ${PROJECT_SOURCE_DIR}/packaging/zonemapd.env.example
        DESTINATION ${CMAKE_INSTALL_DATADIR}/zonemap COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)
# systemd looks in /usr/lib/systemd/system (Debian 12 is usr-merged): relative to the prefix, not
# the multiarch libdir.
install(FILES ${PROJECT_SOURCE_DIR}/packaging/zonemapd@.service DESTINATION lib/systemd/system
        COMPONENT runtime)
if(ZM_UNIT_DROPINS)
  install(DIRECTORY ${ZM_UNIT_DIR}/ DESTINATION lib/systemd/system COMPONENT runtime)
endif()
