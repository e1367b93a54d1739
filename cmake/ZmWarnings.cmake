# One warnings target that every zonemap target links: the same flags everywhere, -Werror in CI.
add_library(zm_warnings INTERFACE)
target_compile_options(zm_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
  -Wunused -Woverloaded-virtual -Wconversion -Wsign-conversion -Wnull-dereference
  -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough)
if(ZM_WERROR)
  target_compile_options(zm_warnings INTERFACE -Werror)
endif()
