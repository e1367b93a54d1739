// Keyframe payload encoding and validation. See keyframe_payload.h for the layout. Decoding is
// on the load path: it checks sizes with 64-bit arithmetic before forming any pointer, so a lying
// header can never make a view reach outside the blob (or, for a decoded slot, the slot).
#include "mapdb/keyframe_payload.h"

#include <zlib.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include "mapdb/map_db_internal.h"  // Kf
#include "simd/crc32c.h"

namespace zm {
namespace {

constexpr std::size_t Align16(std::size_t v) { return (v + 15) & ~std::size_t{15}; }

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

PayloadLayout LayoutFor(std::uint32_t feature_count, std::uint32_t dense_bytes,
                        bool points_on_disk) {
  PayloadLayout l;
  const std::size_t n = feature_count;
  l.descriptors = kPayloadHeaderBytes;
  l.points = Align16(l.descriptors + n * kDescriptorBytes);
  l.keypoints = points_on_disk ? Align16(l.points + n * 3 * sizeof(float)) : l.points;
  l.dense = Align16(l.keypoints + n * 2 * sizeof(float));
  l.total = l.dense + dense_bytes;
  return l;
}

DecodedLayout DecodedLayoutFor(std::size_t total_bytes, std::uint32_t feature_count,
                               std::uint32_t width, std::uint32_t height, std::uint32_t cloud_step,
                               bool points_from_depth) {
  DecodedLayout d;
  const std::size_t pixels = std::size_t{width} * height;
  d.points = Align16(total_bytes);
  d.colour =
      Align16(d.points + (points_from_depth ? std::size_t{feature_count} * 3 * sizeof(float) : 0));
  d.depth = Align16(d.colour + pixels * 3);
  d.cloud = Align16(d.depth + pixels * sizeof(std::uint16_t));
  d.cloud_points = cloud_step == 0 ? 0 : (width / cloud_step) * (height / cloud_step);
  d.end = Align16(d.cloud + std::size_t{d.cloud_points} * 4 * sizeof(float));
  return d;
}

namespace {

// Checks the dense geometry of a kJpegColourRvlDepth payload; "" when valid.
std::string DenseGeometryError(std::uint32_t width, std::uint32_t height, std::uint32_t step,
                               std::uint32_t split, std::uint32_t dense_bytes) {
  if (width < 8 || height < 8 || width > kMaxDenseSide || height > kMaxDenseSide) {
    return "dense image " + std::to_string(width) + "x" + std::to_string(height) +
           " is outside [8, " + std::to_string(kMaxDenseSide) + "] pixels";
  }
  if (step > kMaxCloudStep) {
    return "cloud step " + std::to_string(step) + " exceeds " + std::to_string(kMaxCloudStep);
  }
  if (split == 0 || split >= dense_bytes) {
    return "JPEG part of " + std::to_string(split) + " bytes does not leave an RVL part in " +
           std::to_string(dense_bytes) + " dense bytes";
  }
  return "";
}

}  // namespace

Result<std::size_t> EncodePayload(const PayloadParts& parts, std::span<std::byte> out) {
  const std::size_t n = parts.descriptors.size();
  if (n > kMaxFeaturesPerKeyframe) {
    return InvalidArgument(Kf(parts.id) + ": " + std::to_string(n) +
                           " features exceed the limit of " +
                           std::to_string(kMaxFeaturesPerKeyframe));
  }
  if ((parts.flags & ~kPayloadPointsFromDepth) != 0) {
    return InvalidArgument(Kf(parts.id) + ": unknown payload flags 0x" + [&] {
      char b[16];
      std::snprintf(b, sizeof b, "%x", parts.flags);
      return std::string(b);
    }());
  }
  const bool from_depth = (parts.flags & kPayloadPointsFromDepth) != 0;
  const bool decodes = parts.dense_format == DenseFormat::kJpegColourRvlDepth;
  if (from_depth && !decodes) {
    return InvalidArgument(Kf(parts.id) +
                           ": points from depth need the kJpegColourRvlDepth dense format");
  }
  const std::size_t want_points = from_depth ? 0 : 3 * n;
  if (parts.points.size() != want_points || parts.keypoints.size() != 2 * n) {
    return InvalidArgument(Kf(parts.id) + ": " + std::to_string(n) + " descriptors but " +
                           std::to_string(parts.points.size()) + " point floats and " +
                           std::to_string(parts.keypoints.size()) + " keypoint floats (want " +
                           std::to_string(want_points) + " and " + std::to_string(2 * n) + ")");
  }
  if (parts.dense.size() > std::numeric_limits<std::uint32_t>::max() / 2) {
    return InvalidArgument(Kf(parts.id) + ": dense payload of " +
                           std::to_string(parts.dense.size()) + " bytes is too large");
  }
  if (parts.dense_split > parts.dense.size()) {
    return InvalidArgument(Kf(parts.id) + ": dense_split " + std::to_string(parts.dense_split) +
                           " beyond dense size " + std::to_string(parts.dense.size()));
  }
  const auto dense_bytes = static_cast<std::uint32_t>(parts.dense.size());
  if (decodes) {
    const std::string err = DenseGeometryError(parts.dense_width, parts.dense_height,
                                               parts.cloud_step, parts.dense_split, dense_bytes);
    if (!err.empty()) return InvalidArgument(Kf(parts.id) + ": " + err);
  } else if (parts.dense_width != 0 || parts.dense_height != 0 || parts.cloud_step != 0) {
    return InvalidArgument(Kf(parts.id) +
                           ": dense geometry given for a format that is not decoded");
  }
  const PayloadLayout l = LayoutFor(static_cast<std::uint32_t>(n), dense_bytes, !from_depth);
  const std::size_t resident =
      decodes ? DecodedLayoutFor(l.total, static_cast<std::uint32_t>(n), parts.dense_width,
                                 parts.dense_height, parts.cloud_step, from_depth)
                    .end
              : l.total;
  if (resident > std::numeric_limits<std::uint32_t>::max()) {
    return InvalidArgument(Kf(parts.id) + ": payload of " + std::to_string(resident) +
                           " resident bytes exceeds 4 GiB");
  }
  if (out.size() < l.total) {
    return OutOfRange(Kf(parts.id) + ": payload needs " + std::to_string(l.total) +
                      " bytes, buffer holds " + std::to_string(out.size()));
  }
  std::memset(out.data(), 0, l.total);  // padding is deterministic (same seed, same bytes)
  if (n > 0) {
    std::memcpy(out.data() + l.descriptors, parts.descriptors.data(), n * kDescriptorBytes);
    if (!from_depth) std::memcpy(out.data() + l.points, parts.points.data(), n * 3 * sizeof(float));
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
  h.flags = parts.flags;
  h.resident_bytes = static_cast<std::uint32_t>(resident);
  h.dense_width = static_cast<std::uint16_t>(parts.dense_width);
  h.dense_height = static_cast<std::uint16_t>(parts.dense_height);
  h.cloud_step = static_cast<std::uint16_t>(parts.cloud_step);
  h.body_crc32 = PayloadBodyChecksum(
      kPayloadVersion,
      std::span<const std::byte>(out.data() + kPayloadHeaderBytes, l.total - kPayloadHeaderBytes));
  std::memcpy(out.data(), &h, sizeof h);
  return l.total;
}

Result<std::vector<std::byte>> EncodePayload(const PayloadParts& parts) {
  const std::size_t n = std::min<std::size_t>(parts.descriptors.size(), kMaxFeaturesPerKeyframe);
  const auto dense = static_cast<std::uint32_t>(
      std::min<std::size_t>(parts.dense.size(), std::numeric_limits<std::uint32_t>::max() / 2));
  const bool on_disk = (parts.flags & kPayloadPointsFromDepth) == 0;
  std::vector<std::byte> out(LayoutFor(static_cast<std::uint32_t>(n), dense, on_disk).total);
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
    return FailedPrecondition(
        Kf(id) + ": payload version " + std::to_string(h.version) + ", this build reads versions " +
        std::to_string(kPayloadVersionZlibCrc) + " to " + std::to_string(kPayloadVersion));
  }
  if (h.feature_count > kMaxFeaturesPerKeyframe) {
    return Corrupt(Kf(id) + ": header claims " + std::to_string(h.feature_count) +
                   " features, limit " + std::to_string(kMaxFeaturesPerKeyframe));
  }
  if (h.dense_split > h.dense_bytes) {
    return Corrupt(Kf(id) + ": dense_split " + std::to_string(h.dense_split) + " > dense bytes " +
                   std::to_string(h.dense_bytes));
  }
  if (h.dense_format > kLastDenseFormat) {
    return Corrupt(Kf(id) + ": unknown dense format " + std::to_string(h.dense_format));
  }
  if ((h.flags & ~kPayloadKnownFlags) != 0) {
    return Corrupt(Kf(id) + ": unknown payload flags 0x" + [&] {
      char b[16];
      std::snprintf(b, sizeof b, "%08x", h.flags);
      return std::string(b);
    }());
  }
  const bool decoded = (h.flags & kPayloadDecoded) != 0;
  if (decoded && !blob_is_slot) {
    return Corrupt(Kf(id) + ": a stored payload claims to be decoded (only a slot may)");
  }
  const bool decodes =
      h.dense_format == static_cast<std::uint16_t>(DenseFormat::kJpegColourRvlDepth);
  const bool from_depth = (h.flags & kPayloadPointsFromDepth) != 0;
  if ((from_depth || decoded) && !decodes) {
    return Corrupt(Kf(id) + ": payload flags 0x" + std::to_string(h.flags) +
                   " need the JPEG + RVL dense format, not format " +
                   std::to_string(h.dense_format));
  }
  const PayloadLayout l = LayoutFor(h.feature_count, h.dense_bytes, !from_depth);  // 64-bit math
  if (l.total != h.total_bytes) {
    return Corrupt(Kf(id) + ": header total " + std::to_string(h.total_bytes) +
                   " bytes disagrees with its sections (" + std::to_string(l.total) + " bytes)");
  }
  DecodedLayout d;
  if (decodes) {
    const std::string err = DenseGeometryError(h.dense_width, h.dense_height, h.cloud_step,
                                               h.dense_split, h.dense_bytes);
    if (!err.empty()) return Corrupt(Kf(id) + ": " + err);
    d = DecodedLayoutFor(l.total, h.feature_count, h.dense_width, h.dense_height, h.cloud_step,
                         from_depth);
    if (d.end != h.resident_bytes) {
      return Corrupt(Kf(id) + ": header resident size " + std::to_string(h.resident_bytes) +
                     " bytes disagrees with its decoded sections (" + std::to_string(d.end) +
                     " bytes)");
    }
  } else if ((h.resident_bytes != 0 && h.resident_bytes != h.total_bytes) || h.dense_width != 0 ||
             h.dense_height != 0 || h.cloud_step != 0) {
    return Corrupt(Kf(id) + ": resident size " + std::to_string(h.resident_bytes) +
                   " or dense geometry set for dense format " + std::to_string(h.dense_format) +
                   ", which is not decoded");
  }
  if (blob_is_slot ? blob.size() < l.total : blob.size() != l.total) {
    return Corrupt(Kf(id) + ": payload is " + std::to_string(blob.size()) + " bytes, header says " +
                   std::to_string(l.total) + (blob.size() < l.total ? " (truncated)" : ""));
  }
  if (decoded && blob.size() < d.end) {
    return Corrupt(Kf(id) + ": decoded keyframe needs " + std::to_string(d.end) +
                   " bytes, its slot holds " + std::to_string(blob.size()));
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
  KeyframeView v;
  v.id = id;
  v.feature_count = h.feature_count;
  const auto* base = reinterpret_cast<const std::uint8_t*>(blob.data());
  v.descriptors = base + l.descriptors;
  v.keypoints = reinterpret_cast<const float*>(base + l.keypoints);
  v.dense_format = static_cast<DenseFormat>(h.dense_format);
  v.dense = blob.subspan(l.dense, h.dense_bytes);
  v.dense_split = h.dense_split;
  v.total_bytes = h.total_bytes;
  v.resident_bytes = decodes ? h.resident_bytes : h.total_bytes;
  v.flags = h.flags;
  if (!from_depth) {
    v.points = reinterpret_cast<const float*>(base + l.points);
  } else {
    v.points_frame = PointFrame::kCamera;
    if (decoded) v.points = reinterpret_cast<const float*>(base + d.points);
  }
  if (decodes) {
    v.dense_width = h.dense_width;
    v.dense_height = h.dense_height;
    v.cloud_step = h.cloud_step;
    v.cloud_points = d.cloud_points;
    if (decoded) {
      v.colour = base + d.colour;
      v.depth = reinterpret_cast<const std::uint16_t*>(base + d.depth);
      if (d.cloud_points > 0) v.cloud = reinterpret_cast<const float*>(base + d.cloud);
    }
  }
  return v;
}

}  // namespace zm
