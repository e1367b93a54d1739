// The keyframe payload: the bytes of one keyframe that live in an arena slot while it is
// resident. One blob in the map database, copied verbatim into a slot on load, read in place
// by the localizer (no deserialisation, no allocation).
//
// On disk (little-endian; every section offset is a multiple of 16 so NEON loads align):
//
//   offset 0    PayloadHeader (64 bytes)
//   64          descriptors   feature_count x 32 bytes (256-bit binary descriptors, e.g. ORB)
//   ...         points        feature_count x 3 float32 (x, y, z in the map frame, metres);
//                             ABSENT when flags has kPayloadPointsFromDepth (see below)
//   ...         keypoints     feature_count x 2 float32 (u, v in the keyframe image, pixels)
//   ...         dense         dense_bytes (compressed depth and/or colour, see DenseFormat)
//   total_bytes = LayoutFor(feature_count, dense_bytes, points_on_disk).total
//
// Dense keyframes (DenseFormat::kJpegColourRvlDepth) are decoded INTO their slot on
// load (lib/mapdb/dense_codec.h), after the blob, so a resident keyframe holds what RTAB-Map
// holds in memory for a node, as real data:
//
//   Align16(total_bytes)  points   feature_count x 3 float32, camera frame (x right, y down,
//                                  z forward), from the depth at each keypoint; NaN = no depth
//                                  (only with kPayloadPointsFromDepth)
//   ...                   colour   dense_width x dense_height x 3 uint8 (RGB, row-major)
//   ...                   depth    dense_width x dense_height uint16 (millimetres, 0 = none)
//   ...                   cloud    (w / cloud_step) x (h / cloud_step) x 4 float32 (the pixels at
//                                  multiples of cloud_step, integer division): x, y, z in
//                                  the camera frame (NaN = no depth) and the RGB as uint32 bits
//                                  0x00RRGGBB (PCL's PointXYZRGB packing)
//   resident_bytes = DecodedLayoutFor(...).end  (the slot bytes this keyframe needs)
//
// A blob is valid when: the magic and version match, total_bytes equals the blob length, the
// section sizes add up to total_bytes, resident_bytes agrees with the decoded layout, the
// "decoded" flag is clear (only a slot carries it), and (when checked) the checksum of
// everything after the header matches. DecodePayload() checks all of it and never reads outside
// the blob.
//
// The body checksum is CRC-32C (Castagnoli) since payload version 2: hardware instructions on
// both targets (SSE4.2, the ARMv8 CRC extension; lib/simd/crc32c.h) make it several times
// faster than zlib's CRC-32, which took half of a zone load's time. Version 1 blobs (zlib
// CRC-32) are still read; writers write version 2.
//
// Dense keyframe fields: flags, resident_bytes and the dense geometry live in header bytes that
// were reserved zeros in earlier payloads (of either version), and zero there means what those
// payloads were (points on disk, nothing decoded, resident = total), so every earlier blob still
// loads unchanged. A build from before dense keyframes refuses a dense blob with "unknown dense
// format 6".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"

namespace zm {

inline constexpr std::uint32_t kPayloadMagic = 0x464B4D5A;  // "ZMKF"
inline constexpr std::uint16_t kPayloadVersion = 2;        // written: body checksum CRC-32C
inline constexpr std::uint16_t kPayloadVersionZlibCrc = 1;  // still read: body checksum zlib CRC-32
inline constexpr std::size_t kPayloadHeaderBytes = 64;
inline constexpr std::size_t kDescriptorBytes = 32;  // 256 bits
// A keyframe with more features than this is rejected as corrupt rather than trusted.
inline constexpr std::uint32_t kMaxFeaturesPerKeyframe = 1u << 20;
// Dense images larger than this (per side) are rejected as corrupt.
inline constexpr std::uint32_t kMaxDenseSide = 4096;
inline constexpr std::uint32_t kMaxCloudStep = 16;

enum class DenseFormat : std::uint16_t {
  kNone = 0,
  kPngDepth16 = 1,   // 16UC1 depth in millimetres, PNG (cv::imencode)
  kJpegColour = 2,   // 8UC3 colour, JPEG
  kRvlDepth16 = 3,   // RTAB-Map's RVL depth ("DEPTHRVL" header)
  kPngDepthAndJpegColour = 4,  // PNG depth followed by JPEG colour; see dense_split
  kOpaque = 5,       // bytes carried through unchanged (imports)
  // JPEG colour (dense_split bytes) then RVL depth, both dense_width x dense_height; decoded
  // into the slot on load. RTAB-Map's defaults: Mem/ImageCompressionFormat
  // ".jpg", Mem/DepthCompressionFormat ".rvl".
  kJpegColourRvlDepth = 6,
};
inline constexpr std::uint16_t kLastDenseFormat = 6;

// PayloadHeader::flags.
inline constexpr std::uint32_t kPayloadPointsFromDepth = 1u << 0;  // no points section on disk
inline constexpr std::uint32_t kPayloadDecoded = 1u << 31;         // set in a slot, never on disk
inline constexpr std::uint32_t kPayloadKnownFlags = kPayloadPointsFromDepth | kPayloadDecoded;

using Descriptor256 = std::array<std::uint8_t, kDescriptorBytes>;

struct PayloadHeader {
  std::uint32_t magic;
  std::uint16_t version;
  std::uint16_t dense_format;  // DenseFormat
  std::int64_t keyframe_id;
  std::uint32_t total_bytes;
  std::uint32_t feature_count;
  std::uint32_t dense_bytes;
  std::uint32_t dense_split;  // kPngDepthAndJpegColour, kJpegColourRvlDepth: bytes of part 1
  std::uint32_t body_crc32;   // checksum of bytes [64, total_bytes): PayloadBodyChecksum()
  // Dense keyframes (reserved zeros before them; zero keeps the old meaning):
  std::uint32_t flags;           // kPayload* flags
  std::uint32_t resident_bytes;  // slot bytes once decoded; 0 or total_bytes if nothing decodes
  std::uint16_t dense_width;     // kJpegColourRvlDepth: image size, pixels
  std::uint16_t dense_height;
  std::uint16_t cloud_step;      // decimation of the resident cloud (0 = no cloud)
  std::uint8_t reserved[14];
};
static_assert(sizeof(PayloadHeader) == kPayloadHeaderBytes);

// Which frame a view's points are in.
enum class PointFrame : std::uint8_t {
  kMap = 0,     // map frame (simulated v1 payloads, RTAB-Map imports)
  kCamera = 1,  // the keyframe's camera frame (decoded from depth): T_map_cam * p gives the map
};

// A keyframe's features and dense data, as views into the blob (usually an arena slot). Valid
// only while the blob is; never owns memory.
struct KeyframeView {
  KeyframeId id;
  std::uint32_t feature_count = 0;
  const std::uint8_t* descriptors = nullptr;  // feature_count * 32 bytes, 16-byte aligned
  // feature_count * 3, 16-byte aligned; nullptr for a depth-derived payload not yet decoded
  // (then the keyframe has no 3-D points to verify against). Non-finite = no 3-D position.
  const float* points = nullptr;
  PointFrame points_frame = PointFrame::kMap;
  const float* keypoints = nullptr;           // feature_count * 2
  DenseFormat dense_format = DenseFormat::kNone;
  std::span<const std::byte> dense;
  std::uint32_t dense_split = 0;
  std::uint32_t total_bytes = 0;     // the blob (on disk)
  std::uint32_t resident_bytes = 0;  // what it occupies in its slot (>= total_bytes)
  std::uint32_t flags = 0;
  // Decoded dense data (kJpegColourRvlDepth after decoding in a slot; else null / 0).
  std::uint32_t dense_width = 0;
  std::uint32_t dense_height = 0;
  const std::uint8_t* colour = nullptr;  // dense_width * dense_height * 3, RGB
  const std::uint16_t* depth = nullptr;  // dense_width * dense_height, millimetres
  const float* cloud = nullptr;          // cloud_points * 4 (x, y, z, rgb bits)
  std::uint32_t cloud_points = 0;
  std::uint32_t cloud_step = 0;

  [[nodiscard]] const std::uint8_t* descriptor(std::uint32_t i) const {
    return descriptors + std::size_t{i} * kDescriptorBytes;
  }
  [[nodiscard]] bool decoded() const { return (flags & kPayloadDecoded) != 0; }
};

// Section offsets of the on-disk payload with n features.
struct PayloadLayout {
  std::size_t descriptors = kPayloadHeaderBytes;
  std::size_t points = 0;  // == keypoints when the points are not on disk
  std::size_t keypoints = 0;
  std::size_t dense = 0;
  std::size_t total = 0;
};
[[nodiscard]] PayloadLayout LayoutFor(std::uint32_t feature_count, std::uint32_t dense_bytes,
                                      bool points_on_disk = true);
[[nodiscard]] inline std::size_t PayloadSize(std::uint32_t feature_count, std::uint32_t dense_bytes,
                                             bool points_on_disk = true) {
  return LayoutFor(feature_count, dense_bytes, points_on_disk).total;
}

// Offsets (from the slot start) of what decoding adds after a blob of total_bytes.
struct DecodedLayout {
  std::size_t points = 0;  // feature_count x 3 float32 (empty unless points_from_depth)
  std::size_t colour = 0;
  std::size_t depth = 0;
  std::size_t cloud = 0;
  std::size_t end = 0;  // resident bytes
  std::uint32_t cloud_points = 0;
};
[[nodiscard]] DecodedLayout DecodedLayoutFor(std::size_t total_bytes, std::uint32_t feature_count,
                                             std::uint32_t width, std::uint32_t height,
                                             std::uint32_t cloud_step, bool points_from_depth);

// The parts of a payload to write. points/keypoints hold 3 and 2 floats per feature.
struct PayloadParts {
  KeyframeId id;
  std::span<const Descriptor256> descriptors;
  std::span<const float> points;  // empty with kPayloadPointsFromDepth
  std::span<const float> keypoints;
  DenseFormat dense_format = DenseFormat::kNone;
  std::span<const std::byte> dense;
  std::uint32_t dense_split = 0;
  // kJpegColourRvlDepth only:
  std::uint32_t flags = 0;  // kPayloadPointsFromDepth or 0
  std::uint32_t dense_width = 0;
  std::uint32_t dense_height = 0;
  std::uint32_t cloud_step = 0;  // <= kMaxCloudStep; 0 = no cloud
};

// Writes the payload into `out`, which must hold PayloadSize() bytes; returns the bytes used.
// Errors (mismatched part sizes, out too small) name the keyframe and the sizes.
[[nodiscard]] Result<std::size_t> EncodePayload(const PayloadParts& parts, std::span<std::byte> out);
// Convenience for writers (allocates).
[[nodiscard]] Result<std::vector<std::byte>> EncodePayload(const PayloadParts& parts);

struct DecodeOptions {
  bool verify_crc = true;
  // When set (and verify_crc), the body checksum the caller already computed, piece by piece
  // while the bytes landed (PayloadBodyChecksum with `previous`), compared instead of
  // recomputed: the body is then read once, while it is still in cache.
  const std::uint32_t* body_checksum = nullptr;
};
// Validates `blob` (exactly the payload, or a slot whose first bytes are one: pass
// `blob_is_slot`) and returns views into it. Never reads outside `blob`. In a slot whose header
// carries kPayloadDecoded the decoded sections are exposed too (they must fit in the slot).
[[nodiscard]] Result<KeyframeView> DecodePayload(std::span<const std::byte> blob,
                                                 DecodeOptions options = {},
                                                 bool blob_is_slot = false);

// CRC-32 (zlib polynomial) of a byte range, continuing from `crc` (the CRC of earlier bytes):
// version 1 payloads, and a digest for tests.
[[nodiscard]] std::uint32_t Crc32(std::span<const std::byte> bytes, std::uint32_t crc = 0);
// CRC-32C (Castagnoli) of a byte range continuing from `crc`, with the fastest kernel this CPU
// has (lib/simd/crc32c.h).
[[nodiscard]] std::uint32_t Crc32c(std::span<const std::byte> bytes, std::uint32_t crc = 0);
// The body checksum a payload of `version` carries (CRC-32C for 2, zlib CRC-32 for 1), of
// `body` continuing from `previous`: feed a body in pieces, in order, from previous = 0.
[[nodiscard]] std::uint32_t PayloadBodyChecksum(std::uint16_t version, std::span<const std::byte> body,
                                                std::uint32_t previous = 0);

}  // namespace zm
