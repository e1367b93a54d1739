// Payload round trip and every way a blob can lie about itself, including the dense keyframe
// fields (points from depth, resident size, dense geometry, the slot-only "decoded" flag) and the
// compatibility of blobs written before them.
#include "mapdb/keyframe_payload.h"

#include <doctest/doctest.h>

#include <cstring>
#include <random>

namespace zm {
namespace {

struct Parts {
  std::vector<Descriptor256> desc;
  std::vector<float> pts, kps;
  std::vector<std::byte> dense;
};

Parts MakeParts(std::uint32_t n, std::uint32_t dense, std::uint32_t seed) {
  std::mt19937 rng(seed);
  Parts p;
  p.desc.resize(n);
  for (auto& d : p.desc)
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  for (std::uint32_t i = 0; i < 3 * n; ++i) p.pts.push_back(static_cast<float>(rng() % 1000) * 0.01f);
  for (std::uint32_t i = 0; i < 2 * n; ++i) p.kps.push_back(static_cast<float>(rng() % 640));
  for (std::uint32_t i = 0; i < dense; ++i) p.dense.push_back(static_cast<std::byte>(rng()));
  return p;
}

std::vector<std::byte> Encode(const Parts& p, std::int64_t id) {
  auto r = EncodePayload(PayloadParts{KeyframeId{id}, p.desc, p.pts, p.kps, DenseFormat::kPngDepth16,
                                      p.dense, 0});
  REQUIRE(r.ok());
  return r.value();
}

TEST_CASE("payload round trip keeps every byte and aligns sections") {
  for (std::uint32_t n : {0u, 1u, 7u, 300u}) {
    Parts p = MakeParts(n, 1000 + n, n);
    auto blob = Encode(p, 42);
    CHECK(blob.size() == PayloadSize(n, 1000 + n));
    auto v = DecodePayload(blob);
    REQUIRE(v.ok());
    CHECK(v->id == KeyframeId{42});
    CHECK(v->feature_count == n);
    if (n > 0) {
      CHECK(std::memcmp(v->descriptors, p.desc.data(), n * 32) == 0);
      CHECK(std::memcmp(v->points, p.pts.data(), n * 12) == 0);
      CHECK(std::memcmp(v->keypoints, p.kps.data(), n * 8) == 0);
    }
    CHECK(v->dense.size() == p.dense.size());
    CHECK(std::memcmp(v->dense.data(), p.dense.data(), p.dense.size()) == 0);
    const PayloadLayout l = LayoutFor(n, 1000 + n);
    CHECK(l.points % 16 == 0);
    CHECK(l.keypoints % 16 == 0);
    CHECK(l.dense % 16 == 0);
  }
}

TEST_CASE("a payload inside a larger slot decodes with blob_is_slot") {
  Parts p = MakeParts(10, 100, 1);
  auto blob = Encode(p, 7);
  std::vector<std::byte> slot(blob.size() + 500, std::byte{0xA5});
  std::memcpy(slot.data(), blob.data(), blob.size());
  CHECK_FALSE(DecodePayload(slot).ok());
  CHECK(DecodePayload(slot, {}, true).ok());
}

TEST_CASE("truncated, corrupt and lying blobs are refused with the keyframe named") {
  Parts p = MakeParts(20, 256, 3);
  auto blob = Encode(p, 99);
  SUBCASE("shorter than the header") {
    auto r = DecodePayload(std::span(blob).first(10));
    CHECK(r.status().code() == StatusCode::kCorrupt);
    CHECK(r.status().message().find("truncated") != std::string::npos);
  }
  SUBCASE("truncated body") {
    auto r = DecodePayload(std::span(blob).first(blob.size() - 1));
    CHECK(r.status().code() == StatusCode::kCorrupt);
    CHECK(r.status().message().find("keyframe 99") != std::string::npos);
  }
  SUBCASE("flipped body byte") {
    blob[200] ^= std::byte{1};
    auto r = DecodePayload(blob);
    CHECK(r.status().code() == StatusCode::kCorrupt);
    CHECK(r.status().message().find("checksum") != std::string::npos);
    CHECK(DecodePayload(blob, {.verify_crc = false}).ok());
  }
  SUBCASE("feature count that lies") {
    PayloadHeader h;
    std::memcpy(&h, blob.data(), sizeof h);
    h.feature_count = 0xFFFFFFFFu;
    std::memcpy(blob.data(), &h, sizeof h);
    CHECK(DecodePayload(blob).status().code() == StatusCode::kCorrupt);
    h.feature_count = 21;
    std::memcpy(blob.data(), &h, sizeof h);
    CHECK(DecodePayload(blob).status().code() == StatusCode::kCorrupt);
  }
  SUBCASE("bad magic and version") {
    std::vector<std::byte> other = blob;
    other[0] = std::byte{0};
    CHECK(DecodePayload(other).status().message().find("magic") != std::string::npos);
    PayloadHeader h;
    std::memcpy(&h, blob.data(), sizeof h);
    h.version = 9;
    std::memcpy(blob.data(), &h, sizeof h);
    CHECK(DecodePayload(blob).status().code() == StatusCode::kFailedPrecondition);
  }
}

TEST_CASE("the body checksum is CRC-32C (version 2), version 1 blobs with zlib CRC-32 still read") {
  Parts p = MakeParts(30, 5000, 5);
  auto blob = Encode(p, 12);
  PayloadHeader h;
  std::memcpy(&h, blob.data(), sizeof h);
  const auto body = std::span<const std::byte>(blob).subspan(kPayloadHeaderBytes);
  CHECK(h.version == 2);
  CHECK(h.body_crc32 == Crc32c(body));
  CHECK(h.body_crc32 != Crc32(body));
  CHECK(PayloadBodyChecksum(2, body) == Crc32c(body));
  CHECK(PayloadBodyChecksum(1, body) == Crc32(body));

  SUBCASE("a version 1 blob (zlib CRC-32) decodes, and its checksum is still checked") {
    h.version = kPayloadVersionZlibCrc;
    h.body_crc32 = Crc32(body);
    std::memcpy(blob.data(), &h, sizeof h);
    auto v = DecodePayload(blob);
    REQUIRE_MESSAGE(v.ok(), v.status().ToString());
    CHECK(v->id == KeyframeId{12});
    blob[300] ^= std::byte{4};
    CHECK(DecodePayload(blob).status().message().find("checksum mismatch") != std::string::npos);
  }
  SUBCASE("a version 1 header over a CRC-32C body is a checksum mismatch") {
    h.version = kPayloadVersionZlibCrc;
    std::memcpy(blob.data(), &h, sizeof h);
    CHECK(DecodePayload(blob).status().code() == StatusCode::kCorrupt);
  }
  SUBCASE("a later version is refused naming the versions read") {
    h.version = 3;
    std::memcpy(blob.data(), &h, sizeof h);
    auto r = DecodePayload(blob);
    CHECK(r.status().code() == StatusCode::kFailedPrecondition);
    CHECK(r.status().message().find("payload version 3, this build reads versions 1 to 2") !=
          std::string::npos);
  }
}

TEST_CASE("encode refuses mismatched parts and small buffers") {
  Parts p = MakeParts(5, 10, 4);
  p.pts.pop_back();
  auto r = EncodePayload(PayloadParts{KeyframeId{5}, p.desc, p.pts, p.kps, DenseFormat::kNone, p.dense, 0});
  CHECK(r.status().code() == StatusCode::kInvalidArgument);
  Parts q = MakeParts(5, 10, 4);
  std::vector<std::byte> small(64);
  auto s = EncodePayload(PayloadParts{KeyframeId{5}, q.desc, q.pts, q.kps, DenseFormat::kNone, q.dense, 0},
                         std::span<std::byte>(small));
  CHECK(s.status().code() == StatusCode::kOutOfRange);
}

// A dense payload (kJpegColourRvlDepth, points from depth): the codec is not involved here, the
// dense bytes are opaque to the layout.
std::vector<std::byte> EncodeDense(const Parts& p, std::int64_t id, std::uint32_t w = 64,
                                   std::uint32_t h = 48, std::uint32_t step = 4) {
  PayloadParts parts;
  parts.id = KeyframeId{id};
  parts.descriptors = p.desc;
  parts.keypoints = p.kps;
  parts.dense_format = DenseFormat::kJpegColourRvlDepth;
  parts.dense = p.dense;
  parts.dense_split = static_cast<std::uint32_t>(p.dense.size() / 2);
  parts.flags = kPayloadPointsFromDepth;
  parts.dense_width = w;
  parts.dense_height = h;
  parts.cloud_step = step;
  auto r = EncodePayload(parts);
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  return r.value();
}

PayloadHeader HeaderOf(const std::vector<std::byte>& blob) {
  PayloadHeader h;
  std::memcpy(&h, blob.data(), sizeof h);
  return h;
}

void SetHeader(std::vector<std::byte>& blob, const PayloadHeader& h) { std::memcpy(blob.data(), &h, sizeof h); }

TEST_CASE("dense payloads: no points on disk, the resident size covers the decoded sections") {
  for (std::uint32_t n : {0u, 1u, 7u, 300u}) {
    Parts p = MakeParts(n, 900 + n, n);
    auto blob = EncodeDense(p, 9);
    CHECK(blob.size() == PayloadSize(n, 900 + n, /*points_on_disk=*/false));
    CHECK((blob.size() < PayloadSize(n, 900 + n) || n == 0));
    auto v = DecodePayload(blob);
    REQUIRE(v.ok());
    CHECK(v->points == nullptr);  // not decoded: no 3-D points yet
    CHECK(v->points_frame == PointFrame::kCamera);
    CHECK_FALSE(v->decoded());
    CHECK(v->dense_width == 64);
    CHECK(v->dense_height == 48);
    CHECK(v->cloud_points == 16 * 12);
    if (n > 0) CHECK(std::memcmp(v->keypoints, p.kps.data(), n * 8) == 0);
    const DecodedLayout d = DecodedLayoutFor(blob.size(), n, 64, 48, 4, true);
    CHECK(v->resident_bytes == d.end);
    CHECK(d.points >= blob.size());
    for (std::size_t off : {d.points, d.colour, d.depth, d.cloud, d.end}) CHECK(off % 16 == 0);
    CHECK(d.colour >= d.points + n * 12);
    CHECK(d.depth >= d.colour + 64 * 48 * 3);
    CHECK(d.cloud >= d.depth + 64 * 48 * 2);
    CHECK(d.end >= d.cloud + 16 * 12 * 16);
  }
}

TEST_CASE("dense payloads that lie about their geometry or flags are refused") {
  Parts p = MakeParts(20, 400, 5);
  auto good = EncodeDense(p, 33);
  SUBCASE("resident size") {
    PayloadHeader h = HeaderOf(good);
    h.resident_bytes -= 16;
    SetHeader(good, h);
    auto r = DecodePayload(good);
    CHECK(r.status().code() == StatusCode::kCorrupt);
    CHECK(r.status().message().find("resident") != std::string::npos);
  }
  SUBCASE("image size") {
    PayloadHeader h = HeaderOf(good);
    h.dense_width = 5000;
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().message().find("keyframe 33") != std::string::npos);
  }
  SUBCASE("cloud step") {
    PayloadHeader h = HeaderOf(good);
    h.cloud_step = 17;  // beyond kMaxCloudStep
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().code() == StatusCode::kCorrupt);
  }
  SUBCASE("split") {
    PayloadHeader h = HeaderOf(good);
    h.dense_split = 0;
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().code() == StatusCode::kCorrupt);
  }
  SUBCASE("unknown flags") {
    PayloadHeader h = HeaderOf(good);
    h.flags |= 1u << 7;
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().message().find("flags") != std::string::npos);
  }
  SUBCASE("a stored blob claiming to be decoded") {
    PayloadHeader h = HeaderOf(good);
    h.flags |= kPayloadDecoded;
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().code() == StatusCode::kCorrupt);
    // In a slot too small for the decoded sections the flag is refused too.
    std::vector<std::byte> slot(good.size() + 100);
    std::memcpy(slot.data(), good.data(), good.size());
    CHECK(DecodePayload(slot, {}, true).status().code() == StatusCode::kCorrupt);
  }
  SUBCASE("points from depth on a format that has no depth") {
    PayloadHeader h = HeaderOf(good);
    h.dense_format = static_cast<std::uint16_t>(DenseFormat::kOpaque);
    SetHeader(good, h);
    CHECK(DecodePayload(good).status().code() == StatusCode::kCorrupt);
  }
}

TEST_CASE("blobs from before dense keyframes (reserved header bytes zero) still decode") {
  Parts p = MakeParts(12, 200, 8);
  auto blob = Encode(p, 44);
  PayloadHeader h = HeaderOf(blob);
  CHECK(h.resident_bytes == blob.size());
  h.resident_bytes = 0;  // what every earlier writer left there (the CRC does not cover the header)
  h.flags = 0;
  SetHeader(blob, h);
  auto v = DecodePayload(blob);
  REQUIRE_MESSAGE(v.ok(), v.status().ToString());
  CHECK(v->resident_bytes == blob.size());
  CHECK(v->points_frame == PointFrame::kMap);
  CHECK(std::memcmp(v->points, p.pts.data(), 12 * 12) == 0);
}

TEST_CASE("encode refuses inconsistent dense parts") {
  Parts p = MakeParts(4, 100, 9);
  PayloadParts parts;
  parts.id = KeyframeId{8};
  parts.descriptors = p.desc;
  parts.keypoints = p.kps;
  parts.dense = p.dense;
  parts.dense_split = 50;
  parts.dense_format = DenseFormat::kJpegColourRvlDepth;
  parts.dense_width = 64;
  parts.dense_height = 48;
  parts.flags = kPayloadPointsFromDepth;
  parts.points = p.pts;  // points given AND from depth
  CHECK(EncodePayload(parts).status().code() == StatusCode::kInvalidArgument);
  parts.points = {};
  parts.cloud_step = 40;  // beyond kMaxCloudStep
  CHECK(EncodePayload(parts).status().message().find("cloud step") != std::string::npos);
  parts.cloud_step = 4;
  parts.dense_format = DenseFormat::kOpaque;  // points from depth need depth
  CHECK(EncodePayload(parts).status().code() == StatusCode::kInvalidArgument);
  parts.dense_format = DenseFormat::kJpegColourRvlDepth;
  CHECK(EncodePayload(parts).ok());
}

}  // namespace
}  // namespace zm
