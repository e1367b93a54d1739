// libFuzzer target: the dense keyframe decoder (lib/mapdb/dense_codec.h), which runs on the load
// path over JPEG and RVL bytes that a damaged map (with checksums off) hands it. The input is
//   [u8 width code][u8 height code][u32 split, little-endian][dense bytes: JPEG then RVL]
// wrapped into a valid dense payload, decoded in a slot of exactly its resident size: any write
// outside the slot is an ASan error, a decode that succeeds must leave a decoded, consistent
// view inside it, and a failure must be a Status with a message.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 7) return 0;
  static const auto decoder = [] {
    auto d = zm::DenseDecoder::Create(zm::CameraIntrinsics{320.0, 320.0, 320.0, 240.0, 640, 480});
    if (!d.ok()) std::abort();
    return std::move(d).value();
  }();
  const std::uint32_t width = 8 + 4u * (data[0] % 64u);
  const std::uint32_t height = 8 + 4u * (data[1] % 64u);
  std::uint32_t split = 0;
  std::memcpy(&split, data + 2, 4);
  const std::size_t dense_bytes = size - 6;
  split = 1 + split % static_cast<std::uint32_t>(dense_bytes > 1 ? dense_bytes - 1 : 1);
  if (split >= dense_bytes) return 0;
  std::vector<std::byte> dense(dense_bytes);
  std::memcpy(dense.data(), data + 6, dense_bytes);
  // Three features: inside the image, at its corner, outside it.
  std::vector<zm::Descriptor256> desc(3);
  const std::vector<float> kps = {320.0f, 240.0f, 0.0f, 0.0f, 900.0f, -5.0f};
  zm::PayloadParts parts;
  parts.id = zm::KeyframeId{5};
  parts.descriptors = desc;
  parts.keypoints = kps;
  parts.dense_format = zm::DenseFormat::kJpegColourRvlDepth;
  parts.dense = dense;
  parts.dense_split = split;
  parts.flags = zm::kPayloadPointsFromDepth;
  parts.dense_width = width;
  parts.dense_height = height;
  parts.cloud_step = 1 + data[0] % 8u;
  auto blob = zm::EncodePayload(parts);
  if (!blob.ok()) return 0;
  const auto view = zm::DecodePayload(*blob);
  if (!view.ok()) std::abort();  // EncodePayload wrote it: it must validate
  // A slot of exactly the resident size: one byte more written is an ASan report.
  std::vector<std::byte> slot(view->resident_bytes);
  std::memcpy(slot.data(), blob->data(), blob->size());
  auto landed = decoder->DecodeInSlot(slot, blob->size());
  if (!landed.ok()) {
    if (landed.status().message().empty()) std::abort();
    return 0;
  }
  if (*landed != view->resident_bytes) std::abort();
  auto v = zm::DecodePayload(slot, {}, /*blob_is_slot=*/true);
  if (!v.ok() || !v->decoded() || v->points == nullptr || v->colour == nullptr || v->depth == nullptr) {
    std::abort();
  }
  // Touch what the view exposes.
  unsigned sum = 0;
  for (std::size_t i = 0; i < std::size_t{width} * height * 3; ++i) sum += v->colour[i];
  for (std::size_t i = 0; i < std::size_t{width} * height; ++i) sum += v->depth[i];
  for (std::size_t i = 0; i < 9; ++i) sum += static_cast<unsigned>(v->points[i] == 0.0f);
  if (sum == 0xFFFFFFFFu) std::abort();
  return 0;
}
