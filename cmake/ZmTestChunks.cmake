# cmake -P script, run after a doctest executable links (zm_add_test's POST_BUILD step): lists
# the executable's cases and writes CTEST_FILE, which registers them with ctest in chunks, each
# chunk at most CHUNK consecutive cases of one source file, run as one process with doctest's
# range options (--first / --last over the cases in doctest's default order: by file, then line,
# which --list-test-cases prints in the same order).
#
# Why chunks and not one ctest test per case: a test process costs 0.3-0.9 s of CPU before its
# first line under ASan (the loader relocating a 150 MB executable and OpenCV's 140 shared
# libraries, ASan registering globals, LeakSanitizer's scan at exit) and more under qemu; with
# ~600 cases that start-up was a quarter of the host ctest phase and over half of the qemu one.
# Why chunks and not one test per executable: the two cores stay busy to the end, a failure
# still names a file and a handful of cases, and a chunk's TIMEOUT stays meaningful.
# Ranges, not names: doctest's --test-case filter is a wildcard list split at ',' (a name with
# '*', '?' or ',' needs escaping, and one name can match several cases); a range runs exactly the
# listed cases.
#
# Inputs (-D): TEST_TARGET, TEST_EXECUTABLE, TEST_EXECUTOR (the cross-compiling emulator, may be
# empty), TEST_WORKING_DIR, CHUNK, CTEST_FILE, TEST_TIMEOUT (seconds, per chunk), TEST_LABELS
# ('|'-separated: a ';' would split the -D argument), TEST_RESOURCE_LOCK (may be empty).
cmake_minimum_required(VERSION 3.22)

foreach(v TEST_TARGET TEST_EXECUTABLE TEST_WORKING_DIR CHUNK CTEST_FILE TEST_TIMEOUT)
  if(NOT DEFINED ${v} OR "${${v}}" STREQUAL "")
    message(FATAL_ERROR "ZmTestChunks.cmake: ${v} is not set")
  endif()
endforeach()

execute_process(
  COMMAND ${TEST_EXECUTOR} "${TEST_EXECUTABLE}" --list-test-cases --reporters=xml --no-version
  WORKING_DIRECTORY "${TEST_WORKING_DIR}"
  OUTPUT_VARIABLE listing
  ERROR_VARIABLE listing_err
  RESULT_VARIABLE rc
  TIMEOUT 120)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "listing the cases of ${TEST_EXECUTABLE} failed (${rc}):\n${listing}\n${listing_err}")
endif()

# Names may hold '>' (doctest escapes only '<', '&' and '"' in them) and ';' (which would split
# the list below); only the suite and the file are read, so ';' becomes ',' first.
string(REPLACE ";" "," listing "${listing}")
string(REGEX MATCHALL "<TestCase name=\"[^\"]*\"( testsuite=\"[^\"]*\")? filename=\"[^\"]*\""
       cases "${listing}")
set(props "TIMEOUT ${TEST_TIMEOUT}")
if(NOT "${TEST_LABELS}" STREQUAL "")
  string(REPLACE "|" ";" labels "${TEST_LABELS}")
  string(APPEND props " LABELS [==[${labels}]==]")
endif()
if(NOT "${TEST_RESOURCE_LOCK}" STREQUAL "")
  string(APPEND props " RESOURCE_LOCK [==[${TEST_RESOURCE_LOCK}]==]")
endif()
set(script "# Written by cmake/ZmTestChunks.cmake from ${TEST_TARGET} --list-test-cases.\n")
set(index 0)        # the last case seen: its position in doctest's order, 1-based
set(file "")        # its source file
set(in_file 0)      # its ordinal within that file
set(first 0)        # the open chunk's first case (position), 0: no chunk open
set(chunk_from 0)   # the same, as an ordinal within the file

# Writes the open chunk, cases first..index, as one ctest test; `cost` orders it under ctest -j.
macro(zm_flush_chunk cost)
  if(first GREATER 0)
    get_filename_component(base "${file}" NAME)
    set(test_name "${TEST_TARGET}:${base}:${chunk_from}")
    if(in_file GREATER chunk_from)
      string(APPEND test_name "-${in_file}")
    endif()
    string(APPEND script
      "add_test([==[${test_name}]==] ${TEST_EXECUTOR} [==[${TEST_EXECUTABLE}]==] "
      "--first=${first} --last=${index})\n"
      "set_tests_properties([==[${test_name}]==] PROPERTIES WORKING_DIRECTORY "
      "[==[${TEST_WORKING_DIR}]==] ${props} COST ${cost})\n")
    set(first 0)
  endif()
endmacro()

foreach(c IN LISTS cases)
  if(NOT c MATCHES "filename=\"([^\"]*)\"")
    message(FATAL_ERROR "no filename in ${TEST_TARGET}'s listing: ${c}")
  endif()
  set(case_file "${CMAKE_MATCH_1}")
  # A case in the test suite `slow` (TEST_CASE("..." * doctest::test_suite("slow")), the few
  # that take several seconds to minutes) runs alone, and ctest starts it before the others:
  # in one chunk it would hold one core while the other runs out of work.
  set(slow FALSE)
  if(c MATCHES "testsuite=\"slow\"")
    set(slow TRUE)
  endif()
  if(first GREATER 0)
    math(EXPR size "${index} - ${first} + 1")
    if(NOT case_file STREQUAL file OR slow OR size GREATER_EQUAL CHUNK)
      zm_flush_chunk(1)
    endif()
  endif()
  if(NOT case_file STREQUAL file)
    set(file "${case_file}")
    set(in_file 0)
  endif()
  math(EXPR index "${index} + 1")
  math(EXPR in_file "${in_file} + 1")
  if(first EQUAL 0)
    set(first ${index})
    set(chunk_from ${in_file})
  endif()
  if(slow)
    zm_flush_chunk(100)
  endif()
endforeach()
zm_flush_chunk(1)

file(WRITE "${CTEST_FILE}" "${script}")
