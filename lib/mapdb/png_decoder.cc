// PNG colour images with libpng in fixed memory (see png_decoder.h).
//
// setjmp/longjmp discipline (as dense_codec.cc's for libjpeg): libpng reports errors by calling
// our error function, which must not return; ours records the message and png_longjmp()s back to
// the setjmp in DecodeRaw(), whose locals are all trivial and not modified between the setjmp and
// a longjmp that reads them. Only C frames (libpng, zlib) or our trivial callbacks lie between the
// two, so no destructor is skipped ([csetjmp.syn]).
#include "mapdb/png_decoder.h"

#include <png.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "arena/bump_region.h"

namespace zm {

struct PngDecoder::Impl {
  std::byte* storage = nullptr;  // the pool's memory, 64-byte aligned
  BumpRegion pool;               // over storage; reset after every image
  // The stream being read.
  const unsigned char* src = nullptr;
  std::size_t left = 0;
  // Set by our callbacks before they raise, so the Status says what really happened.
  std::size_t refused_bytes = 0;  // an allocation the pool could not serve
  bool truncated = false;
  char message[160] = {};
  // The size the stream declared.
  std::uint32_t got_width = 0, got_height = 0;

  ~Impl() { std::free(storage); }
};

namespace {

using Impl = PngDecoder::Impl;

constexpr std::size_t kAlign = 16;  // malloc's alignment on both targets

constexpr std::size_t RoundUp(std::size_t v, std::size_t a) { return (v + a - 1) / a * a; }

png_voidp PoolMalloc(png_structp png, png_alloc_size_t bytes) {
  auto* im = static_cast<Impl*>(png_get_mem_ptr(png));
  void* p = im->pool.Take(std::max<png_alloc_size_t>(bytes, 1), kAlign);
  // nullptr: libpng raises "Out of memory" (png_malloc) or copes (png_malloc_warn)
  if (p == nullptr) im->refused_bytes = bytes;
  return p;
}

void PoolFree(png_structp, png_voidp) {}  // the pool is reset after every image

[[noreturn]] void ErrorFn(png_structp png, png_const_charp message) {
  auto* im = static_cast<Impl*>(png_get_error_ptr(png));
  std::snprintf(im->message, sizeof im->message, "%s", message);
  png_longjmp(png, 1);
}

// Warnings (an ancillary chunk's bad CRC, a chunk too long for its kind) change nothing in the
// pixels: libpng has already dropped what it warns about.
void WarningFn(png_structp, png_const_charp) {}

void ReadFn(png_structp png, png_bytep data, std::size_t n) {
  auto* im = static_cast<Impl*>(png_get_io_ptr(png));
  if (n > im->left) {
    im->truncated = true;
    png_error(png, "stream ends early");
  }
  std::memcpy(data, im->src, n);
  im->src += n;
  im->left -= n;
}

enum RawOutcome : int { kRawOk = 0, kRawNoStruct, kRawLibpngError, kRawWrongShape, kRawBadLayout };

// Decodes the stream in `im` into `out` (height rows of width * 3 bytes). Only trivial locals.
int DecodeRaw(Impl* im, std::uint32_t width, std::uint32_t height, std::uint8_t* out) {
  png_structp png = png_create_read_struct_2(PNG_LIBPNG_VER_STRING, im, ErrorFn, WarningFn, im,
                                             PoolMalloc, PoolFree);
  if (png == nullptr) return kRawNoStruct;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return kRawNoStruct;
  }
  if (setjmp(png_jmpbuf(png)) != 0) {
    png_destroy_read_struct(&png, &info, nullptr);
    return kRawLibpngError;
  }
  png_set_read_fn(png, im, ReadFn);
  png_read_info(png, info);
  im->got_width = png_get_image_width(png, info);
  im->got_height = png_get_image_height(png, info);
  if (im->got_width != width || im->got_height != height) {
    png_destroy_read_struct(&png, &info, nullptr);
    return kRawWrongShape;
  }
  const png_byte colour = png_get_color_type(png, info);
  if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if ((colour & PNG_COLOR_MASK_COLOR) == 0) {
    png_set_expand_gray_1_2_4_to_8(png);
    png_set_gray_to_rgb(png);
  }
  png_set_strip_16(png);     // the high byte, as OpenCV's IMREAD_COLOR
  png_set_strip_alpha(png);  // alpha and tRNS: the colour as stored
  const int passes = png_set_interlace_handling(png);
  png_read_update_info(png, info);
  if (png_get_bit_depth(png, info) != 8 || png_get_channels(png, info) != 3 ||
      png_get_rowbytes(png, info) != std::size_t{width} * 3) {
    png_destroy_read_struct(&png, &info, nullptr);
    return kRawBadLayout;
  }
  // Each pass fills its pixels of the same rows: after the last the image is whole (what
  // png_read_image does, without its array of row pointers).
  for (int pass = 0; pass < passes; ++pass) {
    for (std::uint32_t y = 0; y < height; ++y) {
      png_read_row(png, out + std::size_t{y} * width * 3, nullptr);
    }
  }
  png_read_end(png, nullptr);  // the CRCs and zlib check of what follows the last row
  png_destroy_read_struct(&png, &info, nullptr);
  return kRawOk;
}

}  // namespace

PngDecoder::PngDecoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PngDecoder::~PngDecoder() = default;

Result<std::unique_ptr<PngDecoder>> PngDecoder::Create(PngDecoderOptions options) {
  if (options.pool_bytes < 16384) {
    return InvalidArgument("PNG decoder pool of " + std::to_string(options.pool_bytes) +
                           " bytes: at least 16384 (libpng's structures and zlib's state)");
  }
  auto im = std::make_unique<Impl>();
  const std::size_t size = RoundUp(options.pool_bytes, 64);
  im->storage = static_cast<std::byte*>(std::aligned_alloc(64, size));
  if (im->storage == nullptr) {
    return ResourceExhausted("PNG decoder pool of " + std::to_string(size) + " bytes");
  }
  im->pool = BumpRegion{im->storage, size};
  return std::unique_ptr<PngDecoder>(new PngDecoder(std::move(im)));
}

std::size_t PngDecoder::pool_high_water_bytes() const { return impl_->pool.high; }

Status PngDecoder::DecodeRgb(std::span<const std::byte> png, std::uint32_t width,
                             std::uint32_t height, std::span<std::uint8_t> rgb) {
  if (rgb.size() != std::size_t{width} * height * 3) {
    return InvalidArgument("PNG output of " + std::to_string(rgb.size()) + " bytes for a " +
                           std::to_string(width) + "x" + std::to_string(height) + " RGB image");
  }
  const auto* src = reinterpret_cast<const unsigned char*>(png.data());
  if (png.size() < 8 || png_sig_cmp(src, 0, 8) != 0) {
    return Corrupt("not a PNG stream (" + std::to_string(png.size()) +
                   " bytes without the PNG signature)");
  }
  Impl& im = *impl_;
  im.pool.Reset();
  im.src = src;
  im.left = png.size();
  im.refused_bytes = 0;
  im.truncated = false;
  im.message[0] = '\0';
  const int rc = DecodeRaw(&im, width, height, rgb.data());
  if (rc == kRawOk) return Status::Ok();
  const std::string bytes = "PNG of " + std::to_string(png.size()) + " bytes";
  switch (rc) {
    case kRawWrongShape:
      return InvalidArgument(bytes + " is " + std::to_string(im.got_width) + "x" +
                             std::to_string(im.got_height) + ", expected " + std::to_string(width) +
                             "x" + std::to_string(height));
    case kRawBadLayout:
      return Internal(bytes + ": libpng's transforms did not give 8-bit RGB rows");
    default:
      break;
  }
  if (im.refused_bytes != 0 && std::strstr(im.message, "memory") != nullptr) {
    return ResourceExhausted(bytes + ": libpng asked for " + std::to_string(im.refused_bytes) +
                             " more bytes than the decoder's pool of " + std::to_string(im.pool.size) +
                             " (PngDecoderOptions::pool_bytes)");
  }
  if (im.truncated) return Corrupt(bytes + " ends before its image does");
  return Corrupt(bytes + ": " + (im.message[0] != '\0' ? im.message : "libpng error"));
}

}  // namespace zm
