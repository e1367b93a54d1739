# One warnings target that every zonemap target links: the same flags everywhere, -Werror in CI.
add_library(zm_warnings INTERFACE)
target_compile_options(zm_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
  -Wunused -Woverloaded-virtual -Wconversion -Wsign-conversion -Wnull-dereference
  -Wformat=2 -Wimplicit-fallthrough
  # GCC's only. Clang 14's also flags deliberate widenings (double{f}, double d = f); GCC builds
  # every target for aarch64 with it, which catches what matters on the device: float arithmetic
  # silently done in double.
  $<$<CXX_COMPILER_ID:GNU>:-Wdouble-promotion>)
if(ZM_WERROR)
  target_compile_options(zm_warnings INTERFACE -Werror)
endif()
