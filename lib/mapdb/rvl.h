// RVL lossless depth compression (A. D. Wilson, "Fast Lossless Depth Image Compression", 2017)
// in RTAB-Map's container (basic-baseline.md §5): 8-byte magic "DEPTHRVL", uint32 cols, uint32
// rows (little-endian), then the RVL stream of little-endian 32-bit words, each holding eight
// 4-bit nibbles (3 value bits + a continuation bit), most significant nibble first. The stream
// is runs of (zero count, non-zero count, zig-zag deltas of the non-zero values).
//
// The decoder never trusts the stream: it stops with an error naming the pixel and the sizes on
// a run past the image end, a value longer than 32 bits, or input that ends early; it never
// reads outside `blob` or writes outside `out`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/status.h"

namespace zm {

inline constexpr std::size_t kRvlHeaderBytes = 16;
// A header claiming more pixels than this is treated as corrupt (64 Mpx of 16-bit depth).
inline constexpr std::uint64_t kRvlMaxPixels = 1ull << 26;

struct DepthImage16 {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint16_t> pixels;  // row-major, millimetres, 0 = no depth
};

// True when `blob` starts with the "DEPTHRVL" magic.
[[nodiscard]] bool IsRvlDepth(std::span<const std::byte> blob);

// Encodes `depth` (width * height pixels) into RTAB-Map's RVL container.
[[nodiscard]] std::vector<std::byte> EncodeRvlDepth(const DepthImage16& depth);

// Decodes an RTAB-Map RVL blob. Errors name the sizes and where the stream went wrong.
[[nodiscard]] Result<DepthImage16> DecodeRvlDepth(std::span<const std::byte> blob);

// Decodes an RVL blob whose header must say width x height into `out` (exactly width * height
// pixels, row-major, every pixel written), allocating nothing: the load path's form. On error
// `out` holds a partial image.
[[nodiscard]] Status DecodeRvlDepthInto(std::span<const std::byte> blob, std::uint32_t width,
                                        std::uint32_t height, std::span<std::uint16_t> out);

}  // namespace zm
