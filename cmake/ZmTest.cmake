# zm_add_test(name SOURCES a_test.cc ... DEPS zm_x ...): one doctest executable per folder of
# tests/, every TEST_CASE discovered as its own ctest test. When cross-compiling, discovery and
# the tests themselves run through CMAKE_CROSSCOMPILING_EMULATOR (qemu-aarch64).
include(${doctest_DIR}/doctest.cmake OPTIONAL RESULT_VARIABLE ZM_DOCTEST_CMAKE)
if(NOT ZM_DOCTEST_CMAKE)
  find_file(ZM_DOCTEST_CMAKE_FILE doctest.cmake PATHS /usr/lib/cmake/doctest REQUIRED)
  include(${ZM_DOCTEST_CMAKE_FILE})
endif()

function(zm_add_test name)
  cmake_parse_arguments(T "" "RESOURCE_LOCK" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES} ${PROJECT_SOURCE_DIR}/tests/support/doctest_main.cc)
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/tests ${PROJECT_SOURCE_DIR}/lib
                                             ${PROJECT_SOURCE_DIR})
  target_link_libraries(${name} PRIVATE ${T_DEPS} zm_test_support doctest::doctest zm_warnings)
  # The code under test is the libraries', compiled at the build's level; a test's own body
  # (doctest's expanded assertions, fixtures) gains nothing from -O3 and costs a quarter more
  # to compile at it, in every optimised build (aarch64 under qemu, host-release).
  target_compile_options(${name} PRIVATE $<$<CONFIG:Release,RelWithDebInfo>:-O1>)
  target_compile_definitions(${name} PRIVATE
    ZM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    ZM_SHARED_DIR="${PROJECT_SOURCE_DIR}/../shared"
    ZM_BINARY_DIR="${PROJECT_BINARY_DIR}"
    ZM_SIMD_NEON=$<BOOL:${ZM_SIMD_NEON}>)
  set(labels ${T_LABELS})
  if(CMAKE_CROSSCOMPILING)
    list(APPEND labels qemu)
  endif()
  set(props TIMEOUT 600)
  if(labels)
    list(APPEND props LABELS "${labels}")
  endif()
  if(T_RESOURCE_LOCK)  # cases that share a machine-wide resource run one at a time under ctest -j
    list(APPEND props RESOURCE_LOCK ${T_RESOURCE_LOCK})
  endif()
  doctest_discover_tests(${name} PROPERTIES ${props} DISCOVERY_TIMEOUT 120)
endfunction()
