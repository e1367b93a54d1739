# cmake -DCXX=<compiler> -DINCLUDE_DIR=<repo>/include -DWORK_DIR=<dir> -P check_public_headers.cmake
#
# The public API's promise (include/zonemap/zonemap.h): a user needs nothing but the C++20
# standard library to compile against it. For every header under include/zonemap:
#   1. a translation unit including only it compiles with -I<include> alone (-Wall -Wextra
#      -Wpedantic -Werror);
#   2. its include closure (-M) is inside include/zonemap or inside the closure of a unit that
#      includes every standard header (so Eigen, OpenCV, SQLite, toml++, nlohmann, lib/ all fail,
#      even though some of them sit in /usr/include beside libc);
#   3. its text names none of their namespaces or handles (a forward declaration would pass 2).
cmake_minimum_required(VERSION 3.22)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
set(std_headers
  algorithm any array atomic bit bitset cassert cctype cerrno cfloat charconv chrono cinttypes
  climits cmath compare concepts cstddef cstdint cstdio cstdlib cstring ctime exception
  filesystem functional initializer_list iomanip ios iosfwd iostream istream iterator limits
  list map memory mutex new numeric optional ostream random ranges ratio set source_location span
  sstream stdexcept string string_view system_error thread tuple type_traits typeinfo
  unordered_map unordered_set utility variant vector version)
set(std_tu "")
foreach(h ${std_headers})
  string(APPEND std_tu "#include <${h}>\n")
endforeach()
file(WRITE ${WORK_DIR}/std_all.cc "${std_tu}")

function(deps_of source out_var)
  execute_process(COMMAND ${CXX} -std=c++20 -I${INCLUDE_DIR} -M -x c++ ${source}
                  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "public headers: dependency scan of ${source} failed:\n${err}")
  endif()
  string(REPLACE "\\\n" " " out "${out}")
  string(REGEX REPLACE "^[^:]*:" "" out "${out}")
  string(REGEX REPLACE "[ \t\r\n]+" ";" out "${out}")
  set(files "")
  foreach(f ${out})
    if(f STREQUAL "" OR f STREQUAL source)
      continue()
    endif()
    get_filename_component(real "${f}" REALPATH)
    list(APPEND files "${real}")
  endforeach()
  set(${out_var} ${files} PARENT_SCOPE)
endfunction()

deps_of(${WORK_DIR}/std_all.cc std_closure)
list(LENGTH std_closure n_std)
get_filename_component(api_dir ${INCLUDE_DIR}/zonemap REALPATH)
file(GLOB headers ${INCLUDE_DIR}/zonemap/*.h)
set(failures "")
foreach(h ${headers})
  get_filename_component(name ${h} NAME)
  set(tu ${WORK_DIR}/${name}.cc)
  file(WRITE ${tu} "#include \"zonemap/${name}\"\n")
  execute_process(COMMAND ${CXX} -std=c++20 -fsyntax-only -Wall -Wextra -Wpedantic -Werror
                          -I${INCLUDE_DIR} -x c++ ${tu}
                  ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    string(APPEND failures "${name} does not compile alone:\n${err}\n")
    continue()
  endif()
  deps_of(${tu} closure)
  foreach(f ${closure})
    string(FIND "${f}" "${api_dir}/" in_api)
    if(NOT in_api EQUAL 0 AND NOT f IN_LIST std_closure)
      string(APPEND failures "${name} reaches ${f}, outside include/zonemap and the standard library\n")
    endif()
  endforeach()
  file(READ ${h} text)
  string(REGEX REPLACE "//[^\n]*" "" code "${text}")  # comments may name them (and do: why not)
  foreach(word "cv::" "Eigen::" "toml::" "nlohmann::" "zm::" "sqlite3")
    string(FIND "${code}" "${word}" at)
    if(NOT at EQUAL -1)
      string(APPEND failures "${name} names ${word} outside a comment\n")
    endif()
  endforeach()
endforeach()
list(LENGTH headers n_headers)
if(n_headers EQUAL 0)
  message(FATAL_ERROR "public headers: none found under ${INCLUDE_DIR}/zonemap")
endif()
if(failures)
  message(FATAL_ERROR "public headers: FAILED\n${failures}")
endif()
message(STATUS "public headers: ok (${n_headers} headers; closure checked against ${n_std} standard library files)")
