// The global operator new/delete of a zonemap program, and (in builds without a sanitizer) its
// malloc family: a request made inside a ScratchScope is served from that scope's FrameScratch
// (arena/frame_scratch.h), every other one by glibc's allocator, as without this file. The
// malloc side exists because OpenCV's FAST takes its row buffers with cv::fastMalloc (malloc)
// through cv::utils::BufferArea, once per pyramid level and frame. Linked (as the object library
// zm_scratch_new) into the programs whose tick calls a library that allocates per frame
// (OpenCV's ORB); the test suites' counting allocator (tests/support/counting_allocator.cc) is
// the same replacement (replace_allocator.h) with counters in its hooks, so there is one
// replacement per executable either way.
#include <cstddef>

namespace zm::alloc_hooks {
// A program counts nothing.
void OnHeapNew(std::size_t) noexcept {}
void OnHeapDelete() noexcept {}
void OnHeapMalloc() noexcept {}
}  // namespace zm::alloc_hooks

#include "arena/replace_allocator.h"
