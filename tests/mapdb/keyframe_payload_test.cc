// Payload round trip and every way a blob can lie about itself.
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

TEST_CASE("the body checksum is CRC-32C (version 2); version 1 blobs with zlib CRC-32 still read") {
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

}  // namespace
}  // namespace zm
