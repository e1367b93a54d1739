# cmake -P tests/test_names.cmake SOURCE_DIR: fails naming every doctest case whose name holds a
# ';'. doctest_discover_tests registers each case as a ctest test whose command filters by the
# name, and CMake splits that command at the ';', so such a case runs no test at all and ctest
# reports it passed. Twenty cases had done so; this keeps it from happening again.
file(GLOB_RECURSE sources "${SOURCE_DIR}/tests/*.cc")
set(bad "")
foreach(f ${sources})
  file(READ "${f}" text)
  # A name is one or more adjacent string literals after TEST_CASE(.
  string(REGEX MATCHALL "TEST_CASE\\([ \t\r\n]*(\"[^\"]*\"[ \t\r\n]*)+\\)" cases "${text}")
  foreach(c IN LISTS cases)
    # MATCHALL's list is split at ';' too: a piece without the closing ')' is a broken name.
    if(NOT c MATCHES "\\)$")
      file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
      string(APPEND bad "\n  ${rel}: ${c}")
    endif()
  endforeach()
endforeach()
if(bad)
  message(FATAL_ERROR "test case names with ';' (ctest would run none of them):${bad}")
endif()
