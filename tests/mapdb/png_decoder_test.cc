// The front-end's PNG decoder (lib/mapdb/png_decoder.h): every PNG colour type, depth and
// interlacing reads as OpenCV's IMREAD_COLOR reads it (cv::imdecode is the reference here, in the
// test only), a warm decode allocates nothing, and every kind of bad stream is one error naming
// it, after which the decoder still works.
#include "mapdb/png_decoder.h"

#include <doctest/doctest.h>
#include <png.h>

#include <csetjmp>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

std::vector<std::byte> Bytes(const std::vector<std::uint8_t>& v) {
  std::vector<std::byte> out(v.size());
  std::memcpy(out.data(), v.data(), v.size());
  return out;
}

std::vector<std::byte> Encode(const cv::Mat& m, const std::vector<int>& params = {}) {
  std::vector<std::uint8_t> buf;
  REQUIRE(cv::imencode(".png", m, buf, params));
  return Bytes(buf);
}

cv::Mat Random(int h, int w, int type, std::uint32_t seed) {
  cv::Mat m(h, w, type);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
  return m;
}

// What OpenCV decodes, as RGB bytes.
std::vector<std::uint8_t> Reference(const std::vector<std::byte>& png) {
  const cv::Mat buf(1, static_cast<int>(png.size()), CV_8UC1, const_cast<std::byte*>(png.data()));
  const cv::Mat bgr = cv::imdecode(buf, cv::IMREAD_COLOR);
  REQUIRE(!bgr.empty());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return std::vector<std::uint8_t>(rgb.data, rgb.data + rgb.total() * 3);
}

// A palette image (4-bit indices), optionally Adam7-interlaced: libpng's own writer, since
// OpenCV writes neither.
std::vector<std::byte> PalettePng(int w, int h, bool interlaced, std::uint32_t seed) {
  struct Sink {
    std::vector<std::byte> out;
    static void Write(png_structp p, png_bytep d, std::size_t n) {
      auto* s = static_cast<Sink*>(png_get_io_ptr(p));
      const auto* b = reinterpret_cast<const std::byte*>(d);
      s->out.insert(s->out.end(), b, b + n);
    }
    static void Flush(png_structp) {}
  } sink;
  std::mt19937 rng(seed);
  std::vector<png_color> palette(16);
  for (png_color& c : palette) {
    c.red = static_cast<png_byte>(rng());
    c.green = static_cast<png_byte>(rng());
    c.blue = static_cast<png_byte>(rng());
  }
  const std::size_t stride = (static_cast<std::size_t>(w) + 1) / 2;
  std::vector<png_byte> pixels(stride * static_cast<std::size_t>(h));
  for (png_byte& b : pixels) b = static_cast<png_byte>(rng());
  std::vector<png_bytep> rows(static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y) {
    rows[static_cast<std::size_t>(y)] = pixels.data() + stride * static_cast<std::size_t>(y);
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  REQUIRE(png != nullptr);
  REQUIRE(info != nullptr);
  if (setjmp(png_jmpbuf(png)) != 0) FAIL("libpng could not write the palette image");
  png_set_write_fn(png, &sink, Sink::Write, Sink::Flush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(w), static_cast<png_uint_32>(h), 4,
               PNG_COLOR_TYPE_PALETTE, interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_PLTE(png, info, palette.data(), 16);
  png_byte alpha[3] = {0, 128, 255};  // tRNS: read as the colour, alpha dropped
  png_set_tRNS(png, info, alpha, 3, nullptr);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return sink.out;
}

std::unique_ptr<PngDecoder> Make(PngDecoderOptions o = {}) {
  auto d = PngDecoder::Create(o);
  REQUIRE(d.ok());
  return std::move(d).value();
}

TEST_CASE("png decoder: every colour type, depth and interlacing reads as OpenCV reads it") {
  auto dec = Make();
  constexpr int kW = 97, kH = 61;  // odd sizes: partial interlace blocks, odd 4-bit rows
  struct Case {
    std::string name;
    std::vector<std::byte> png;
  };
  std::vector<Case> cases = {
      {"grey 8", Encode(Random(kH, kW, CV_8UC1, 1))},
      {"RGB 8", Encode(Random(kH, kW, CV_8UC3, 2))},
      {"RGBA 8", Encode(Random(kH, kW, CV_8UC4, 3))},
      {"grey 16", Encode(Random(kH, kW, CV_16UC1, 4))},
      {"RGB 16", Encode(Random(kH, kW, CV_16UC3, 5))},
      {"RGBA 16", Encode(Random(kH, kW, CV_16UC4, 6))},
      {"grey 1-bit", Encode(Random(kH, kW, CV_8UC1, 7) > 128, {cv::IMWRITE_PNG_BILEVEL, 1})},
      {"RGB 8, fastest zlib", Encode(Random(kH, kW, CV_8UC3, 8), {cv::IMWRITE_PNG_COMPRESSION, 0})},
      {"palette 4-bit", PalettePng(kW, kH, false, 9)},
      {"palette 4-bit, Adam7", PalettePng(kW, kH, true, 10)},
  };
  std::vector<std::uint8_t> rgb(std::size_t{kW} * kH * 3);
  for (const Case& c : cases) {
    CAPTURE(c.name);
    std::fill(rgb.begin(), rgb.end(), std::uint8_t{0xEE});
    const Status s = dec->DecodeRgb(c.png, kW, kH, rgb);
    REQUIRE_MESSAGE(s.ok(), s.message());
    CHECK(rgb == Reference(c.png));
  }
  // Sized: small images need a few KiB to tens of KiB (libpng's rows, zlib's state and window),
  // far below the default pool.
  MESSAGE("PNG decoder pool high water: " << dec->pool_high_water_bytes() << " bytes");
  CHECK(dec->pool_high_water_bytes() > 0);
  CHECK(dec->pool_high_water_bytes() < PngDecoderOptions{}.pool_bytes / 2);
}

TEST_CASE("png decoder: a warm decode allocates nothing from the heap") {
  auto dec = Make();
  const std::vector<std::byte> a = Encode(Random(240, 320, CV_8UC3, 11));
  const std::vector<std::byte> b = PalettePng(320, 240, true, 12);
  std::vector<std::uint8_t> rgb(std::size_t{320} * 240 * 3);
  REQUIRE(dec->DecodeRgb(a, 320, 240, rgb).ok());  // warm-up
  test::AllocationCounter news;
  test::MallocCounter mallocs;
  REQUIRE(dec->DecodeRgb(b, 320, 240, rgb).ok());
  REQUIRE(dec->DecodeRgb(a, 320, 240, rgb).ok());
  CHECK(news.allocations() == 0);
  CHECK(mallocs.mallocs() == 0);
}

TEST_CASE("png decoder: bad streams are one error each, and the decoder goes on") {
  auto dec = Make();
  const std::vector<std::byte> good = Encode(Random(30, 40, CV_8UC3, 13));
  std::vector<std::uint8_t> rgb(std::size_t{40} * 30 * 3);
  const auto error = [&](const std::vector<std::byte>& png) {
    const Status s = dec->DecodeRgb(png, 40, 30, rgb);
    return s.ok() ? std::string("ok") : s.message();
  };
  CHECK(error({}) == "not a PNG stream (0 bytes without the PNG signature)");
  std::vector<std::byte> noise(good.size(), std::byte{0x5A});
  CHECK(error(noise).find("without the PNG signature") != std::string::npos);
  // Cut anywhere after the signature: in the header, in the image data, before the end chunk.
  for (const std::size_t keep :
       {std::size_t{12}, std::size_t{40}, good.size() / 2, good.size() - 12, good.size() - 1}) {
    CAPTURE(keep);
    const std::vector<std::byte> cut(good.begin(), good.begin() + static_cast<long>(keep));
    CHECK(error(cut) == "PNG of " + std::to_string(keep) + " bytes ends before its image does");
  }
  // A flipped byte inside the image data: zlib's check (or the chunk's CRC) fails.
  std::vector<std::byte> flipped = good;
  flipped[good.size() / 2] ^= std::byte{0x40};
  const std::string crc = error(flipped);
  CHECK(crc.find("PNG of " + std::to_string(good.size()) + " bytes: IDAT: ") == 0);
  // Another size: refused from the header, naming both.
  CHECK(error(Encode(Random(10, 12, CV_8UC3, 14))).find("is 12x10, expected 40x30") !=
        std::string::npos);
  // An output buffer that is not the image's.
  std::vector<std::uint8_t> small(10);
  CHECK(dec->DecodeRgb(good, 40, 30, small).message() ==
        "PNG output of 10 bytes for a 40x30 RGB image");
  REQUIRE(dec->DecodeRgb(good, 40, 30, rgb).ok());
  CHECK(rgb == Reference(good));
}

TEST_CASE("png decoder: a pool too small is refused at Create or named at the decode") {
  CHECK(PngDecoder::Create({.pool_bytes = 1000}).status().message() ==
        "PNG decoder pool of 1000 bytes: at least 16384 (libpng's structures and zlib's state)");
  auto dec = Make({.pool_bytes = 16384});
  const std::vector<std::byte> png = Encode(Random(200, 2000, CV_8UC3, 15));
  std::vector<std::uint8_t> rgb(std::size_t{2000} * 200 * 3);
  const Status s = dec->DecodeRgb(png, 2000, 200, rgb);
  CHECK(s.code() == StatusCode::kResourceExhausted);
  CHECK(s.message().find("than the decoder's pool of 16384 (PngDecoderOptions::pool_bytes)") !=
        std::string::npos);
}

}  // namespace
}  // namespace zm
