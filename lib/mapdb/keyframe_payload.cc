// Keyframe payload encoding and validation. See keyframe_payload.h for the layout. Decoding is
// on the load path: it checks sizes with 64-bit arithmetic before forming any pointer, so a lying
// header can never make a view reach outside the blob.
#include "mapdb/keyframe_payload.h"

#include <zlib.h>

#include <cstring>
#include <limits>
#include <string>

#include "simd/crc32c.h"

namespace zm {
namespace {

constexpr std::size_t Align16(std::size_t v) { return (v + 15) & ~std::size_t{15}; }

std::string Kf(KeyframeId id) { return "keyframe " + std::to_string(id.value); }

}  // namespace

std::uint32_t Crc32(std::span<const std::byte> bytes, std::uint32_t previous) {
  uLong crc = previous;
  const auto* p = reinterpret_cast<const Bytef*>(bytes.data());
  std::size_t left = bytes.size();
  // zlib takes uInt lengths; feed large ranges in chunks.
  while (left > 0) {
    const auto chunk = static_cast<uInt>(std::min<std::size_t>(left, 1u << 30));
    crc = crc32(crc, p, chunk);
    p += chunk;
    left -= chunk;
  }
  return static_cast<std::uint32_t>(crc);
}

std::uint32_t Crc32c(std::span<const std::byte> bytes, std::uint32_t crc) {
  return simd::Crc32c(bytes.data(), bytes.size(), crc);
}

std::uint32_t PayloadBodyChecksum(std::uint16_t version, std::span<const std::byte> body,
                                  std::uint32_t previous) {
  return version == kPayloadVersionZlibCrc ? Crc32(body, previous) : Crc32c(body, previous);
}

PayloadLayout LayoutFor(std::uint32_t feature_count, std::uint32_t dense_bytes) {
  PayloadLayout l;
  const std::size_t n = feature_count;
  l.descriptors = kPayloadHeaderBytes;
  l.points = Align16(l.descriptors + n * kDescriptorBytes);
  l.keypoints = Align16(l.points + n * 3 * sizeof(float));
  l.dense = Align16(l.keypoints + n * 2 * sizeof(float));
  l.total = l.dense + dense_bytes;
  return l;
}

Result<std::size_t> EncodePayload(const PayloadParts& parts, std::span<std::byte> out) {
  const std::size_t n = parts.descriptors.size();
  if (n > kMaxFeaturesPerKeyframe) {
    return InvalidArgument(Kf(parts.id) + ": " + std::to_string(n) + " features exceed the limit of " +
                           std::to_string(kMaxFeaturesPerKeyframe));
  }
  if (parts.points.size() != 3 * n || parts.keypoints.size() != 2 * n) {
    return InvalidArgument(Kf(parts.id) + ": " + std::to_string(n) + " descriptors but " +
                           std::to_string(parts.points.size()) + " point floats and " +
                           std::to_string(parts.keypoints.size()) + " keypoint floats (want " +
                           std::to_string(3 * n) + " and " + std::to_string(2 * n) + ")");
  }
  if (parts.dense.size() > std::numeric_limits<std::uint32_t>::max() / 2) {
    return InvalidArgument(Kf(parts.id) + ": dense payload of " + std::to_string(parts.dense.size()) +
                           " bytes is too large");
  }
  if (parts.dense_split > parts.dense.size()) {
    return InvalidArgument(Kf(parts.id) + ": dense_split " + std::to_string(parts.dense_split) +
                           " beyond dense size " + std::to_string(parts.dense.size()));
  }
  const auto dense_bytes = static_cast<std::uint32_t>(parts.dense.size());
  const PayloadLayout l = LayoutFor(static_cast<std::uint32_t>(n), dense_bytes);
  if (l.total > std::numeric_limits<std::uint32_t>::max()) {
    return InvalidArgument(Kf(parts.id) + ": payload of " + std::to_string(l.total) +
                           " bytes exceeds 4 GiB");
  }
  if (out.size() < l.total) {
    return OutOfRange(Kf(parts.id) + ": payload needs " + std::to_string(l.total) +
                      " bytes, buffer holds " + std::to_string(out.size()));
  }
  std::memset(out.data(), 0, l.total);  // padding is deterministic (same seed, same bytes)
  if (n > 0) {
    std::memcpy(out.data() + l.descriptors, parts.descriptors.data(), n * kDescriptorBytes);
    std::memcpy(out.data() + l.points, parts.points.data(), n * 3 * sizeof(float));
    std::memcpy(out.data() + l.keypoints, parts.keypoints.data(), n * 2 * sizeof(float));
  }
  if (dense_bytes > 0) std::memcpy(out.data() + l.dense, parts.dense.data(), dense_bytes);

  PayloadHeader h{};
  h.magic = kPayloadMagic;
  h.version = kPayloadVersion;
  h.dense_format = static_cast<std::uint16_t>(parts.dense_format);
  h.keyframe_id = parts.id.value;
  h.total_bytes = static_cast<std::uint32_t>(l.total);
  h.feature_count = static_cast<std::uint32_t>(n);
  h.dense_bytes = dense_bytes;
  h.dense_split = parts.dense_split;
  h.body_crc32 = PayloadBodyChecksum(
      kPayloadVersion,
      std::span<const std::byte>(out.data() + kPayloadHeaderBytes, l.total - kPayloadHeaderBytes));
  std::memcpy(out.data(), &h, sizeof h);
  return l.total;
}

Result<std::vector<std::byte>> EncodePayload(const PayloadParts& parts) {
  const std::size_t n = parts.descriptors.size();
  std::vector<std::byte> out(LayoutFor(static_cast<std::uint32_t>(
                                           std::min<std::size_t>(n, kMaxFeaturesPerKeyframe)),
                                       static_cast<std::uint32_t>(std::min<std::size_t>(
                                           parts.dense.size(), std::numeric_limits<std::uint32_t>::max() / 2)))
                                 .total);
  auto r = EncodePayload(parts, std::span<std::byte>(out));
  if (!r.ok()) return r.status();
  out.resize(r.value());
  return out;
}

Result<KeyframeView> DecodePayload(std::span<const std::byte> blob, DecodeOptions options,
                                   bool blob_is_slot) {
  if (blob.size() < kPayloadHeaderBytes) {
    return Corrupt("keyframe payload of " + std::to_string(blob.size()) +
                   " bytes is shorter than its " + std::to_string(kPayloadHeaderBytes) +
                   "-byte header (truncated)");
  }
  PayloadHeader h;
  std::memcpy(&h, blob.data(), sizeof h);
  if (h.magic != kPayloadMagic) {
    return Corrupt("keyframe payload has bad magic 0x" + [&] {
      char b[16];
      std::snprintf(b, sizeof b, "%08x", h.magic);
      return std::string(b);
    }() + " (not a zonemap keyframe)");
  }
  const KeyframeId id{h.keyframe_id};
  if (h.version != kPayloadVersion && h.version != kPayloadVersionZlibCrc) {
    return FailedPrecondition(Kf(id) + ": payload version " + std::to_string(h.version) +
                              ", this build reads versions " +
                              std::to_string(kPayloadVersionZlibCrc) + " to " +
                              std::to_string(kPayloadVersion));
  }
  if (h.feature_count > kMaxFeaturesPerKeyframe) {
    return Corrupt(Kf(id) + ": header claims " + std::to_string(h.feature_count) +
                   " features, limit " + std::to_string(kMaxFeaturesPerKeyframe));
  }
  if (h.dense_split > h.dense_bytes) {
    return Corrupt(Kf(id) + ": dense_split " + std::to_string(h.dense_split) + " > dense bytes " +
                   std::to_string(h.dense_bytes));
  }
  const PayloadLayout l = LayoutFor(h.feature_count, h.dense_bytes);  // 64-bit math, no overflow
  if (l.total != h.total_bytes) {
    return Corrupt(Kf(id) + ": header total " + std::to_string(h.total_bytes) +
                   " bytes disagrees with its sections (" + std::to_string(l.total) + " bytes)");
  }
  if (blob_is_slot ? blob.size() < l.total : blob.size() != l.total) {
    return Corrupt(Kf(id) + ": payload is " + std::to_string(blob.size()) + " bytes, header says " +
                   std::to_string(l.total) + (blob.size() < l.total ? " (truncated)" : ""));
  }
  if (options.verify_crc) {
    const std::uint32_t crc =
        options.body_checksum != nullptr
            ? *options.body_checksum
            : PayloadBodyChecksum(h.version,
                                  blob.subspan(kPayloadHeaderBytes, l.total - kPayloadHeaderBytes));
    if (crc != h.body_crc32) {
      return Corrupt(Kf(id) + ": payload checksum mismatch (corrupt blob of " +
                     std::to_string(l.total) + " bytes)");
    }
  }
  if (h.dense_format > static_cast<std::uint16_t>(DenseFormat::kOpaque)) {
    return Corrupt(Kf(id) + ": unknown dense format " + std::to_string(h.dense_format));
  }
  KeyframeView v;
  v.id = id;
  v.feature_count = h.feature_count;
  const auto* base = reinterpret_cast<const std::uint8_t*>(blob.data());
  v.descriptors = base + l.descriptors;
  v.points = reinterpret_cast<const float*>(base + l.points);
  v.keypoints = reinterpret_cast<const float*>(base + l.keypoints);
  v.dense_format = static_cast<DenseFormat>(h.dense_format);
  v.dense = blob.subspan(l.dense, h.dense_bytes);
  v.dense_split = h.dense_split;
  v.total_bytes = h.total_bytes;
  return v;
}

}  // namespace zm
