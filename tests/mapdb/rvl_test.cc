// RVL depth codec: the exact bit layout RTAB-Map writes, round trips, and a decoder that refuses
// every malformed stream without reading or writing out of bounds.
#include "mapdb/rvl.h"

#include <doctest/doctest.h>

#include <cstring>
#include <random>

namespace zm {
namespace {

std::vector<std::byte> Bytes(std::initializer_list<int> v) {
  std::vector<std::byte> out;
  for (int b : v) out.push_back(static_cast<std::byte>(b));
  return out;
}

TEST_CASE("RVL writes RTAB-Map's container and nibble order") {
  // Pixels {0, 5}: zeros=1 -> nibble 1; nonzeros=1 -> 1; zig-zag(5)=10 -> nibbles A (2|more), 1.
  // Word 0x11A1 padded to 0x11A10000, stored little-endian.
  const DepthImage16 img{2, 1, {0, 5}};
  const auto blob = EncodeRvlDepth(img);
  std::vector<std::byte> want = Bytes({'D', 'E', 'P', 'T', 'H', 'R', 'V', 'L', 2, 0, 0, 0, 1, 0, 0, 0,
                                       0x00, 0x00, 0xA1, 0x11});
  CHECK(blob == want);
  auto back = DecodeRvlDepth(blob);
  REQUIRE(back.ok());
  CHECK(back->pixels == img.pixels);
}

TEST_CASE("RVL round trips depth with holes, jumps and the 16-bit extremes") {
  std::mt19937 rng(3);
  for (const auto& [w, h] : {std::pair{1u, 1u}, {7u, 3u}, {64u, 48u}, {33u, 17u}}) {
    DepthImage16 img{w, h, std::vector<std::uint16_t>(std::size_t{w} * h)};
    for (auto& p : img.pixels) {
      const auto r = rng() % 10;
      p = r < 3 ? 0 : r == 9 ? 65535 : static_cast<std::uint16_t>(500 + rng() % 4000);
    }
    auto back = DecodeRvlDepth(EncodeRvlDepth(img));
    REQUIRE(back.ok());
    CHECK(back->width == w);
    CHECK(back->height == h);
    CHECK(back->pixels == img.pixels);
  }
  DepthImage16 zeros{16, 16, std::vector<std::uint16_t>(256, 0)};
  auto back = DecodeRvlDepth(EncodeRvlDepth(zeros));
  REQUIRE(back.ok());
  CHECK(back->pixels == zeros.pixels);
}

TEST_CASE("RVL decoder refuses malformed streams with a clear error") {
  DepthImage16 img{8, 8, std::vector<std::uint16_t>(64, 1234)};
  auto good = EncodeRvlDepth(img);
  SUBCASE("no header") {
    auto r = DecodeRvlDepth(std::span(good).first(10));
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("DEPTHRVL header") != std::string::npos);
  }
  SUBCASE("stream ends early") {
    good.resize(good.size() - 8);
    auto r = DecodeRvlDepth(good);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("stream ends") != std::string::npos);
  }
  SUBCASE("header claims more pixels than the stream holds") {
    good[8] = std::byte{200};
    auto r = DecodeRvlDepth(good);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("200x8") != std::string::npos);
  }
  SUBCASE("header claims an absurd size") {
    good[11] = std::byte{0x7f};
    auto r = DecodeRvlDepth(good);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("limit") != std::string::npos);
  }
  SUBCASE("run past the image end") {
    DepthImage16 small{2, 1, {0, 5}};
    auto blob = EncodeRvlDepth(small);
    blob[19] = std::byte{0x71};  // zero run of 7 in a 2-pixel image
    auto r = DecodeRvlDepth(blob);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("past the image end") != std::string::npos);
  }
  SUBCASE("all continuation bits") {
    std::vector<std::byte> blob(good.begin(), good.begin() + 16);
    blob.insert(blob.end(), 64, std::byte{0xff});
    auto r = DecodeRvlDepth(blob);
    REQUIRE_FALSE(r.ok());
  }
}

}  // namespace
}  // namespace zm
