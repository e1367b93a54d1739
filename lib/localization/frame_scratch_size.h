// The frame scratch (arena/frame_scratch.h) the ORB front-end needs for frames of a size, with
// room to spare: see the measurement in docs/localization.md ("Allocation inside the tick"). The
// pyramid and its blurred copies scale with the pixels, the keypoint vectors with max_features.
// What the region then reserves is FrameScratch::ReservedBytes of it (whole pages).
//
// Header-only: the memory budget (runtime/budget.h, part of libzonemap) sizes the region without
// linking the extractor (zm_localization_orb, OpenCV's features2d).
#pragma once

#include <cstddef>
#include <cstdint>

namespace zm {

[[nodiscard]] inline std::size_t FrameScratchBytesFor(std::uint32_t width, std::uint32_t height) {
  const std::size_t pixels = std::size_t{width} * height;
  return 8 * pixels + (std::size_t{2} << 20);
}

}  // namespace zm
