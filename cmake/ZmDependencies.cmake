# Every dependency comes from a Debian package (scripts/install-deps.sh installs them).
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs calib3d features2d)
find_package(SQLite3 REQUIRED)
find_package(ZLIB REQUIRED)
# Dense keyframes: JPEG colour through libjpeg-turbo with our own memory manager (dense_codec.cc).
find_package(JPEG REQUIRED)
# PNG camera frames in the loop's front-end: libpng with our own allocator (png_decoder.cc), so
# the on-device core does not link OpenCV's imgcodecs (and the GDAL it pulls in).
find_package(PNG REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(tomlplusplus REQUIRED)
find_package(CLI11 REQUIRED)
find_package(doctest REQUIRED)

# mimalloc: the host has the -dev package with a CMake config; Debian's arm64 package ships only
# the shared library, so fall back to finding that (the header is architecture independent).
find_package(mimalloc QUIET)
if(NOT TARGET mimalloc)
  find_library(ZM_MIMALLOC_LIBRARY NAMES mimalloc libmimalloc.so.2)
  find_path(ZM_MIMALLOC_INCLUDE NAMES mimalloc.h PATH_SUFFIXES mimalloc-2.0)
  if(ZM_MIMALLOC_LIBRARY AND ZM_MIMALLOC_INCLUDE)
    add_library(mimalloc SHARED IMPORTED)
    set_target_properties(mimalloc PROPERTIES IMPORTED_LOCATION "${ZM_MIMALLOC_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${ZM_MIMALLOC_INCLUDE}")
  endif()
endif()

if(ZM_BUILD_BENCH)
  find_package(benchmark QUIET)
endif()
