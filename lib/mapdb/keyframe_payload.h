// The keyframe payload: the bytes of one keyframe that live in an arena slot while it is
// resident. One blob in the map database, copied verbatim into a slot on load, read in place
// by the localizer (no deserialisation, no allocation).
//
// Layout (little-endian; every section offset is a multiple of 16 so NEON loads align):
//
//   offset 0    PayloadHeader (64 bytes)
//   64          descriptors   feature_count x 32 bytes (256-bit binary descriptors, e.g. ORB)
//   ...         points        feature_count x 3 float32 (x, y, z in the map frame, metres)
//   ...         keypoints     feature_count x 2 float32 (u, v in the keyframe image, pixels)
//   ...         dense         dense_bytes (compressed depth and/or colour, see DenseFormat)
//   total_bytes = PayloadSize(feature_count, dense_bytes)
//
// A blob is valid when: the magic and version match, total_bytes equals the blob length, the
// section sizes add up to total_bytes, and (when checked) the checksum of everything after the
// header matches. DecodePayload() checks all of it and never reads outside the blob.
//
// The body checksum is CRC-32C (Castagnoli) since payload version 2: hardware instructions on
// both targets (SSE4.2, the ARMv8 CRC extension; lib/simd/crc32c.h) make it several times
// faster than zlib's CRC-32, which took half of a zone load's time. Version 1 blobs (zlib
// CRC-32) are still read; writers write version 2.
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

enum class DenseFormat : std::uint16_t {
  kNone = 0,
  kPngDepth16 = 1,   // 16UC1 depth in millimetres, PNG (cv::imencode)
  kJpegColour = 2,   // 8UC3 colour, JPEG
  kRvlDepth16 = 3,   // RTAB-Map's RVL depth ("DEPTHRVL" header)
  kPngDepthAndJpegColour = 4,  // PNG depth followed by JPEG colour; see dense_split
  kOpaque = 5,       // bytes carried through unchanged (imports)
};

using Descriptor256 = std::array<std::uint8_t, kDescriptorBytes>;

struct PayloadHeader {
  std::uint32_t magic;
  std::uint16_t version;
  std::uint16_t dense_format;  // DenseFormat
  std::int64_t keyframe_id;
  std::uint32_t total_bytes;
  std::uint32_t feature_count;
  std::uint32_t dense_bytes;
  std::uint32_t dense_split;  // kPngDepthAndJpegColour: bytes of the first part; else 0
  std::uint32_t body_crc32;   // checksum of bytes [64, total_bytes): PayloadBodyChecksum()
  std::uint8_t reserved[28];
};
static_assert(sizeof(PayloadHeader) == kPayloadHeaderBytes);

// A keyframe's features and dense bytes, as views into the blob (usually an arena slot). Valid
// only while the blob is; never owns memory.
struct KeyframeView {
  KeyframeId id;
  std::uint32_t feature_count = 0;
  const std::uint8_t* descriptors = nullptr;  // feature_count * 32 bytes, 16-byte aligned
  const float* points = nullptr;              // feature_count * 3
  const float* keypoints = nullptr;           // feature_count * 2
  DenseFormat dense_format = DenseFormat::kNone;
  std::span<const std::byte> dense;
  std::uint32_t dense_split = 0;
  std::uint32_t total_bytes = 0;

  [[nodiscard]] const std::uint8_t* descriptor(std::uint32_t i) const {
    return descriptors + std::size_t{i} * kDescriptorBytes;
  }
};

// Section offsets for a payload with n features.
struct PayloadLayout {
  std::size_t descriptors = kPayloadHeaderBytes;
  std::size_t points = 0;
  std::size_t keypoints = 0;
  std::size_t dense = 0;
  std::size_t total = 0;
};
[[nodiscard]] PayloadLayout LayoutFor(std::uint32_t feature_count, std::uint32_t dense_bytes);
[[nodiscard]] inline std::size_t PayloadSize(std::uint32_t feature_count, std::uint32_t dense_bytes) {
  return LayoutFor(feature_count, dense_bytes).total;
}

// The parts of a payload to write. points/keypoints hold 3 and 2 floats per feature.
struct PayloadParts {
  KeyframeId id;
  std::span<const Descriptor256> descriptors;
  std::span<const float> points;
  std::span<const float> keypoints;
  DenseFormat dense_format = DenseFormat::kNone;
  std::span<const std::byte> dense;
  std::uint32_t dense_split = 0;
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
// `blob_is_slot`) and returns views into it. Never reads outside `blob`.
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
