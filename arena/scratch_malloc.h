// The C allocator's side of the frame scratch (frame_scratch.h): what an interposed malloc,
// calloc, realloc, aligned allocation and malloc_usable_size do with a block of a FrameScratch.
// Shared by the programs' allocator (scratch_new.cc) and the test suites' counting allocator,
// so both behave alike. Only builds without a sanitizer interpose malloc (AddressSanitizer owns
// it), so under ASan the C allocator's requests inside a scope still reach the heap.
//
// A C block needs its size (realloc, malloc_usable_size), which the bump region does not keep:
// it is stored in the 16 bytes before the pointer. Everything here is noexcept and allocates
// nothing from the heap itself.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "arena/frame_scratch.h"

namespace zm::scratch_c {

inline constexpr std::size_t kHeader = 16;

// A block of n bytes aligned to `align` (a power of two >= 16) from this thread's scope, or
// nullptr when there is no scope or it does not fit.
inline void* Allocate(std::size_t n, std::size_t align = kHeader) noexcept {
  if (align < kHeader) align = kHeader;
  const std::size_t want = n + kHeader + (align - kHeader);
  if (want < n) return nullptr;
  auto* raw = static_cast<unsigned char*>(ScratchAllocate(want, kHeader));
  if (raw == nullptr) return nullptr;
  const auto first = reinterpret_cast<std::uintptr_t>(raw) + kHeader;
  const std::uintptr_t p = (first + align - 1) & ~(std::uintptr_t{align} - 1);
  std::memcpy(reinterpret_cast<void*>(p - kHeader), &n, sizeof n);
  return reinterpret_cast<void*>(p);
}

inline std::size_t Size(const void* p) noexcept {
  std::size_t n = 0;
  std::memcpy(&n, static_cast<const unsigned char*>(p) - kHeader, sizeof n);
  return n;
}

}  // namespace zm::scratch_c
