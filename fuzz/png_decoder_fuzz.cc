// libFuzzer target: the front-end's PNG decoder (lib/mapdb/png_decoder.h), which reads whatever
// bytes a camera driver (or a damaged recording) hands zonemapd as a PNG frame. The input is the
// PNG stream itself; the expected size is the one its header declares when that is small (so the
// decoder gets past the size check and into libpng's pixel paths), else 64x64. The output is an
// exact-size heap buffer: any write outside it is an ASan error; a failure must be a Status with
// a message; the pool's high-water mark must stay inside the pool.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "mapdb/png_decoder.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto decoder = [] {
    auto d = zm::PngDecoder::Create();
    if (!d.ok()) std::abort();
    return std::move(d).value();
  }();
  std::uint32_t width = 64, height = 64;
  if (size >= 24) {  // signature (8), IHDR length and type (8), then width and height, big-endian
    const auto be32 = [&](std::size_t at) {
      return std::uint32_t{data[at]} << 24 | std::uint32_t{data[at + 1]} << 16 |
             std::uint32_t{data[at + 2]} << 8 | std::uint32_t{data[at + 3]};
    };
    const std::uint32_t w = be32(16), h = be32(20);
    if (w >= 1 && w <= 256 && h >= 1 && h <= 256) {
      width = w;
      height = h;
    }
  }
  std::vector<std::byte> png(size);
  if (size > 0) std::memcpy(png.data(), data, size);
  std::vector<std::uint8_t> rgb(std::size_t{width} * height * 3);
  const zm::Status s = decoder->DecodeRgb(png, width, height, rgb);
  if (!s.ok() && s.message().empty()) std::abort();
  if (decoder->pool_high_water_bytes() > zm::PngDecoderOptions{}.pool_bytes) std::abort();
  return 0;
}
