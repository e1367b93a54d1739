// libFuzzer target: the keyframe payload decoder (lib/mapdb/keyframe_payload.h). DecodePayload
// must never read outside the blob (ASan), and a blob it accepts must have every section inside
// the blob. Also fed as a "slot" (blob_is_slot), where trailing bytes are allowed.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "mapdb/keyframe_payload.h"

namespace {

void CheckView(const zm::KeyframeView& v, std::span<const std::byte> blob) {
  const auto* lo = reinterpret_cast<const std::uint8_t*>(blob.data());
  const auto* hi = lo + blob.size();
  const auto inside = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    return n == 0 || (b >= lo && b + n <= hi);
  };
  const std::size_t n = v.feature_count;
  const std::size_t pixels = std::size_t{v.dense_width} * v.dense_height;
  // Points are absent until a dense payload is decoded in a slot; decoded sections only exist in
  // a slot that claims them, and must then lie inside it.
  if (!inside(v.descriptors, n * zm::kDescriptorBytes) ||
      (v.points != nullptr && !inside(v.points, n * 12)) || !inside(v.keypoints, n * 8) ||
      !inside(v.dense.data(), v.dense.size()) || v.total_bytes > blob.size() ||
      (v.colour != nullptr && !inside(v.colour, pixels * 3)) ||
      (v.depth != nullptr && !inside(v.depth, pixels * 2)) ||
      (v.cloud != nullptr && !inside(v.cloud, std::size_t{v.cloud_points} * 16))) {
    std::abort();
  }
  // Touch every byte the view exposes, so ASan sees any out-of-bounds section.
  unsigned sum = 0;
  for (std::size_t i = 0; i < n * zm::kDescriptorBytes; ++i) sum += v.descriptors[i];
  for (std::size_t i = 0; v.points != nullptr && i < 3 * n; ++i) sum += static_cast<unsigned>(v.points[i] == 0.0f);
  for (std::size_t i = 0; v.colour != nullptr && i < 3 * pixels; ++i) sum += v.colour[i];
  for (std::size_t i = 0; v.depth != nullptr && i < pixels; ++i) sum += v.depth[i];
  for (std::size_t i = 0; i < 2 * n; ++i) sum += static_cast<unsigned>(v.keypoints[i] == 0.0f);
  for (std::byte b : v.dense) sum += static_cast<unsigned>(b);
  if (sum == 0xFFFFFFFFu) std::abort();  // keep the loop
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // Copy into a 16-byte aligned buffer of exactly `size` bytes (DecodePayload's section pointers
  // are meant to be aligned; ASan still catches a read past the end of the heap block).
  std::vector<std::byte> blob(size);
  if (size > 0) std::memcpy(blob.data(), data, size);
  for (bool crc : {true, false}) {
    for (bool slot : {false, true}) {
      auto v = zm::DecodePayload(blob, zm::DecodeOptions{.verify_crc = crc}, slot);
      if (v.ok()) CheckView(*v, blob);
      else if (v.status().message().empty()) std::abort();
    }
  }
  return 0;
}
