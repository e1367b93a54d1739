// Dense keyframes: the colour and depth images of a keyframe, compressed on disk and decoded into
// the keyframe's arena slot on load, so a resident keyframe holds real RGB-D data the size of what
// RTAB-Map keeps per node (docs/sim.md, "Dense keyframes").
//
// Codecs are Debian's: libjpeg-turbo for colour (JPEG, baseline 4:2:0, RTAB-Map's default
// Mem/ImageCompressionFormat ".jpg") and RTAB-Map's RVL for depth (lib/mapdb/rvl.h,
// Mem/DepthCompressionFormat ".rvl"). The payload layout is in keyframe_payload.h.
//
// The decoder runs on the load path, once per keyframe, right after its blob is validated in its
// slot. It allocates nothing once warm: libjpeg's memory manager (jpeg_memory_mgr, a public,
// replaceable struct of function pointers) is replaced by a bump allocator over two fixed pools
// reserved in Create() -- a permanent pool (Huffman and quantisation tables, the source manager:
// filled on the first image, then reused) and an image pool reset after every image -- and RVL
// decodes straight into the slot. libjpeg errors AND warnings (a truncated stream, extraneous
// bytes) come back through setjmp/longjmp as one Status naming the keyframe; progressive or
// multi-scan JPEG (which needs whole-image "virtual arrays") is refused. Everything is written
// inside [0, resident_bytes) of the slot, which is checked against the slot size first.
//
// Not thread-safe: one decoder per loading thread (the loop has one).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "common/status.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "mapdb/rvl.h"

namespace zm {

// --- Writer side (the simulator; allocates) ---------------------------------------------------

// Baseline JPEG (4:2:0, standard Huffman tables, libjpeg-turbo) of a row-major RGB image of
// width * height * 3 bytes; quality in [1, 100].
[[nodiscard]] Result<std::vector<std::byte>> EncodeJpegRgb(std::span<const std::uint8_t> rgb,
                                                           std::uint32_t width,
                                                           std::uint32_t height, int quality);

// A dense keyframe's payload (kJpegColourRvlDepth, the features' 3-D points from the depth):
// what the simulator and the importers write.
struct DenseKeyframeImages {
  std::span<const std::uint8_t> rgb;    // width * height * 3, row-major
  const DepthImage16* depth = nullptr;  // width * height, millimetres
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  int jpeg_quality = 95;
  std::uint32_t cloud_step = 0;  // the resident cloud's decimation
};
struct DenseKeyframePayload {
  std::vector<std::byte> payload;  // EncodePayload's blob
  std::uint32_t jpeg_bytes = 0;
  std::uint32_t rvl_bytes = 0;
  std::uint32_t resident_bytes = 0;  // the slot bytes it takes decoded (DecodedLayoutFor)
};
// Encodes the colour as JPEG, the depth as RVL, and the payload of keyframe `id` with its
// features (descriptors, 2 keypoint coordinates each). Errors are EncodeJpegRgb's and
// EncodePayload's.
[[nodiscard]] Result<DenseKeyframePayload> EncodeDenseKeyframe(
    KeyframeId id, std::span<const Descriptor256> descriptors, std::span<const float> keypoints,
    const DenseKeyframeImages& images);

// --- Load side ----------------------------------------------------------------------------------

struct DenseDecoderOptions {
  // libjpeg's working memory per image (strip buffers, upsampling, MCU blocks) grows with the
  // image width: 34 KB at 640 columns, 152 KB at the 4096-column limit (measured,
  // tests/mapdb/dense_codec_test.cc), so 512 KiB leaves room for other sampling factors.
  std::size_t jpeg_image_pool_bytes = std::size_t{512} << 10;
  std::size_t jpeg_permanent_pool_bytes = std::size_t{64} << 10;
};

// A keypoint's 3-D point from a depth image: the depth at the pixel holding (u, v) of the
// keypoint camera (same field of view as the depth image), back-projected with that camera's
// intrinsics. Camera frame, metres; NaN when the pixel has no depth.
void PointFromDepth(const CameraIntrinsics& camera, const std::uint16_t* depth_mm,
                    std::uint32_t width, std::uint32_t height, float u, float v, float out[3]);

class DenseDecoder {
 public:
  // Reserves all working memory (libjpeg's decompressor and its pools) once. `camera` is the
  // map's keypoint camera (map metadata): depth-derived points need it.
  [[nodiscard]] static Result<std::unique_ptr<DenseDecoder>> Create(
      const CameraIntrinsics& camera, DenseDecoderOptions options = {});
  ~DenseDecoder();
  DenseDecoder(const DenseDecoder&) = delete;
  DenseDecoder& operator=(const DenseDecoder&) = delete;

  // Decodes the payload at the start of `slot` (exactly `blob_bytes` long, validated by
  // DecodePayload) into the rest of the slot: colour, depth, the feature points from depth and
  // the decimated cloud; then marks the slot's header decoded. Returns the keyframe's resident
  // bytes (total_bytes for formats that do not decode, which are left untouched). Errors name the
  // keyframe: a resident size larger than the slot (out_of_range), corrupt JPEG or RVL data
  // (corrupt), no camera for points (failed_precondition). Allocation-free once warm.
  [[nodiscard]] Result<std::uint32_t> DecodeInSlot(std::span<std::byte> slot, std::size_t blob_bytes);

  // JPEG -> RGB into `out` (exactly width * height * 3 bytes), refusing another size or a
  // non-colour image. Allocation-free once warm. (DecodeInSlot's colour step; tests use it.)
  [[nodiscard]] Status DecodeJpegRgb(std::span<const std::byte> jpeg, std::uint32_t width,
                                     std::uint32_t height, std::span<std::uint8_t> out);

  // Most of libjpeg's image pool used by one image so far (to size the pool).
  [[nodiscard]] std::size_t jpeg_pool_high_water_bytes() const;

  struct Impl;

 private:
  explicit DenseDecoder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace zm
