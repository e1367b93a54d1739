// BumpRegion: a bump allocator over a region someone else owns, for a C library's allocator
// hooks (libjpeg's memory manager in lib/mapdb/dense_codec.cc, libpng's malloc_fn in
// lib/mapdb/png_decoder.cc). The decoder reserves its region once at Create(); after that
// every allocation the library makes while decoding one image is a pointer bump, and the
// decoder resets the region between images. Nothing here allocates or frees.
//
// Why not FrameScratch (frame_scratch.h): that one serves operator new for any caller inside a
// scope and must survive blocks outliving it; a codec's hook knows exactly when every block is
// dead (the image is done), so a reset is all it needs, and a refusal must reach the library as
// nullptr (libjpeg and libpng then raise their own "out of memory", which the decoders turn into
// a Status naming the region and its size).
#pragma once

#include <algorithm>
#include <cstddef>

namespace zm {

struct BumpRegion {
  std::byte* base = nullptr;
  std::size_t size = 0;
  std::size_t used = 0;
  std::size_t high = 0;  // most bytes in use at once since creation (to size the region)

  // `n` bytes rounded up to `align` (a power of two; the base must be aligned to it, and every
  // caller of one region uses the same `align`, so `used` stays a multiple of it), or nullptr
  // when they do not fit. Never overflows: n is checked against the size before rounding.
  void* Take(std::size_t n, std::size_t align) {
    if (n > size) return nullptr;
    const std::size_t rounded = (n + align - 1) & ~(align - 1);
    if (rounded > size - used) return nullptr;
    void* p = base + used;
    used += rounded;
    high = std::max(high, used);
    return p;
  }
  void Reset() { used = 0; }
};

}  // namespace zm
