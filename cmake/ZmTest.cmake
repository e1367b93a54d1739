# zm_add_test(name SOURCES a_test.cc ... DEPS zm_x ...): one doctest executable per folder of
# tests/. After it links, cmake/ZmTestChunks.cmake lists its cases and registers them with ctest
# in chunks of at most ZM_TEST_CHUNK consecutive cases of one source file (that script says why),
# named `executable:file.cc:first-last` (the cases' ordinals in the file; one case alone:
# `executable:file.cc:n`). When cross-compiling,
# the listing and the tests themselves run through CMAKE_CROSSCOMPILING_EMULATOR (qemu-aarch64).
# One case alone: run the executable with --test-case="its name" (or -sf=FILE to run one file).
set(ZM_TEST_CHUNK 8 CACHE STRING "Most doctest cases of one source file per ctest test")
set(ZM_TEST_CHUNKS_SCRIPT ${CMAKE_CURRENT_LIST_DIR}/ZmTestChunks.cmake)

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
  list(JOIN labels "|" labels)
  get_property(emulator TARGET ${name} PROPERTY CROSSCOMPILING_EMULATOR)
  set(tests_file ${CMAKE_CURRENT_BINARY_DIR}/${name}_chunks.cmake)
  # T_RESOURCE_LOCK: cases that share a machine-wide resource run one at a time under ctest -j.
  add_custom_command(TARGET ${name} POST_BUILD
    BYPRODUCTS ${tests_file}
    COMMAND ${CMAKE_COMMAND} -D TEST_TARGET=${name} -D TEST_EXECUTABLE=$<TARGET_FILE:${name}>
            "-D" "TEST_EXECUTOR=${emulator}" -D TEST_WORKING_DIR=${CMAKE_CURRENT_BINARY_DIR}
            -D CHUNK=${ZM_TEST_CHUNK} -D TEST_TIMEOUT=600 "-D" "TEST_LABELS=${labels}"
            "-D" "TEST_RESOURCE_LOCK=${T_RESOURCE_LOCK}" -D CTEST_FILE=${tests_file}
            -P ${ZM_TEST_CHUNKS_SCRIPT}
    VERBATIM)
  set(include_file ${CMAKE_CURRENT_BINARY_DIR}/${name}_include.cmake)
  file(WRITE ${include_file}
    "if(EXISTS \"${tests_file}\")\n"
    "  include(\"${tests_file}\")\n"
    "else()\n"
    "  add_test(${name}_NOT_BUILT ${name}_NOT_BUILT)\n"
    "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${include_file})
  # For tests/test_chunks.cmake, which checks that the chunks run every case exactly once.
  set_property(GLOBAL APPEND PROPERTY ZM_TEST_CHUNK_PAIRS "$<TARGET_FILE:${name}>|${tests_file}")
endfunction()
