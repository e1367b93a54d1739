// PngDecoder: a PNG colour image into a caller's RGB buffer, with libpng in fixed memory. The
// loop's front-end reads PNG camera frames with it (JPEG frames go through DenseDecoder).
//
// Why not cv::imdecode: OpenCV's imgcodecs (Debian's build) loads GDAL, GDCM, poppler, HDF5 and
// some 130 other shared libraries into every process that links it. On zonemapd that was 0.13 s
// of start-up and 36 MB of RSS, 10 MB of it private dirty (their relocations and static
// initialisers), taken from the co-tenant's budget, for one PNG read per frame. libpng alone is
// what imgcodecs used underneath.
//
// Memory: libpng's allocator is ours (png_create_read_struct_2): a bump pool reserved once in
// Create() and reset after every image, so a decode allocates nothing from the heap. Errors come
// back through setjmp/longjmp (png_decoder.cc says how that stays clear of C++ objects) as one
// Status.
//
// Any PNG colour type and depth is read as 8-bit RGB, the way OpenCV's IMREAD_COLOR reads it:
// palette expanded, grey replicated, alpha and transparency dropped, 16-bit samples truncated to
// their high byte; interlaced images are de-interlaced in place. The image must be exactly
// width x height: checked from the header, before a pixel is written.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "common/status.h"

namespace zm {

struct PngDecoderOptions {
  // libpng's structures, its row buffers and zlib's inflate window (32 KiB) for one image. A
  // 640x480 RGB image needs about 60 KiB (png_decoder_test prints the high-water mark).
  std::size_t pool_bytes = std::size_t{256} << 10;
};

class PngDecoder {
 public:
  [[nodiscard]] static Result<std::unique_ptr<PngDecoder>> Create(PngDecoderOptions options = {});
  ~PngDecoder();
  PngDecoder(const PngDecoder&) = delete;
  PngDecoder& operator=(const PngDecoder&) = delete;

  // Decodes `png` into `rgb` (width * height * 3 bytes, row-major, R G B). A stream that is not
  // a PNG, truncated, corrupt (a CRC or zlib error), of another size, or needing more than the
  // pool is one Status (the size error names both sizes); `rgb` may then hold part of an image.
  // Allocation-free.
  [[nodiscard]] Status DecodeRgb(std::span<const std::byte> png, std::uint32_t width,
                                 std::uint32_t height, std::span<std::uint8_t> rgb);

  // Most of the pool one image has used so far (to size the pool).
  [[nodiscard]] std::size_t pool_high_water_bytes() const;

  struct Impl;

 private:
  explicit PngDecoder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace zm
