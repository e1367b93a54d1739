// Dense keyframe codecs (see dense_codec.h). The JPEG decoder's memory manager and error handler
// are ours; libjpeg-turbo does the decoding.
//
// setjmp/longjmp discipline: libjpeg reports errors by calling error_exit, which must not return.
// Ours longjmps back to the setjmp in a *Raw() function whose locals are all trivial and not
// modified after the setjmp, and only C frames (libjpeg) or our trivial callbacks lie between
// the two, so no destructor is skipped ([csetjmp.syn]).
#include "mapdb/dense_codec.h"

// clang-format off
#include <cstdio>  // jpeglib.h needs FILE
#include <jpeglib.h>
#include <jerror.h>
// clang-format on

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

#include "arena/bump_region.h"
#include "mapdb/map_db_internal.h"  // Kf
#include "mapdb/rvl.h"

namespace zm {
namespace {

constexpr std::size_t kAlign = 64;  // >= libjpeg-turbo's ALIGN_SIZE (32), a cache line

constexpr std::size_t RoundUp(std::size_t v, std::size_t a) { return (v + a - 1) / a * a; }

// libjpeg's error manager plus where to jump and the formatted message.
struct JpegError {
  jpeg_error_mgr pub;  // first: libjpeg hands &pub back as cinfo->err
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

void ErrorExit(j_common_ptr c) {
  auto* e = reinterpret_cast<JpegError*>(c->err);
  (*c->err->format_message)(c, e->message);
  std::longjmp(e->jump, 1);
}

// Warnings (a truncated stream padded with a fake EOI, extraneous bytes, bad Huffman codes) are
// errors here: a keyframe decoded from damaged data must not be handed to the localizer.
void EmitMessage(j_common_ptr c, int level) {
  if (level < 0) ErrorExit(c);
}

void OutputMessage(j_common_ptr) {}

void InstallErrorHandler(JpegError* e) {
  jpeg_std_error(&e->pub);
  e->pub.error_exit = ErrorExit;
  e->pub.emit_message = EmitMessage;
  e->pub.output_message = OutputMessage;
  e->message[0] = '\0';
}


}  // namespace

struct DenseDecoder::Impl {
  CameraIntrinsics camera;
  bool has_camera = false;
  std::byte* storage = nullptr;  // both pools, 64-byte aligned
  std::size_t storage_bytes = 0;
  BumpRegion permanent, image;  // libjpeg's two pools, in storage
  jpeg_decompress_struct cinfo{};
  JpegError err{};
  jpeg_memory_mgr mgr{};
  jpeg_memory_mgr* libjpeg_mgr = nullptr;  // libjpeg's own, holding what create allocated
  bool created = false;
  // Set by our callbacks before they raise, so the Status says what really happened.
  const char* refusal = nullptr;
  std::size_t refused_bytes = 0;
  // The shape the stream declared when it was not the keyframe's.
  std::uint32_t got_width = 0, got_height = 0;
  int got_components = 0;

  ~Impl() {
    if (created) {
      cinfo.mem = libjpeg_mgr;  // libjpeg frees what it allocated at create; our pools are ours
      jpeg_destroy_decompress(&cinfo);
    }
    std::free(storage);
  }
};

namespace {

using Impl = DenseDecoder::Impl;

Impl* Of(j_common_ptr c) { return static_cast<Impl*>(c->client_data); }

[[noreturn]] void Raise(j_common_ptr c, int code) {
  c->err->msg_code = code;
  (*c->err->error_exit)(c);
  std::abort();  // error_exit longjmps
}

BumpRegion* PoolFor(j_common_ptr c, int pool_id) {
  Impl* im = Of(c);
  if (pool_id == JPOOL_PERMANENT) return &im->permanent;
  if (pool_id == JPOOL_IMAGE) return &im->image;
  c->err->msg_parm.i[0] = pool_id;
  Raise(c, JERR_BAD_POOL_ID);
}

void* AllocSmall(j_common_ptr c, int pool_id, std::size_t bytes) {
  void* p = PoolFor(c, pool_id)->Take(bytes, kAlign);
  if (p == nullptr) {
    Impl* im = Of(c);
    im->refusal = pool_id == JPOOL_IMAGE ? "image pool" : "permanent pool";
    im->refused_bytes = bytes;
    c->err->msg_parm.i[0] = 0;
    Raise(c, JERR_OUT_OF_MEMORY);
  }
  return p;
}

// Rows padded to 2 * 32 samples and 32-byte aligned, as libjpeg-turbo's SIMD kernels expect
// (its jmemmgr.c does the same): they may read and write up to the padded row end.
JSAMPARRAY AllocSarray(j_common_ptr c, int pool_id, JDIMENSION samples_per_row, JDIMENSION rows) {
  const std::size_t row_bytes = RoundUp(samples_per_row, 64) * sizeof(JSAMPLE);
  auto* result =
      static_cast<JSAMPARRAY>(AllocSmall(c, pool_id, std::size_t{rows} * sizeof(JSAMPROW)));
  const std::size_t total = std::size_t{rows} * row_bytes;
  auto* space = static_cast<JSAMPROW>(AllocSmall(c, pool_id, std::max<std::size_t>(total, 1)));
  for (JDIMENSION r = 0; r < rows; ++r) result[r] = space + std::size_t{r} * row_bytes;
  return result;
}

JBLOCKARRAY AllocBarray(j_common_ptr c, int pool_id, JDIMENSION blocks_per_row, JDIMENSION rows) {
  auto* result =
      static_cast<JBLOCKARRAY>(AllocSmall(c, pool_id, std::size_t{rows} * sizeof(JBLOCKROW)));
  const std::size_t total = std::size_t{rows} * blocks_per_row * sizeof(JBLOCK);
  auto* space = static_cast<JBLOCKROW>(AllocSmall(c, pool_id, std::max<std::size_t>(total, 1)));
  for (JDIMENSION r = 0; r < rows; ++r) result[r] = space + std::size_t{r} * blocks_per_row;
  return result;
}

// Whole-image ("virtual") arrays are only needed for progressive / multi-scan files and buffered
// image mode; dense keyframes are baseline JPEG, so a request means a file we do not decode.
[[noreturn]] void RefuseVirtual(j_common_ptr c) {
  Of(c)->refusal = "progressive or multi-scan JPEG (dense keyframes are baseline JPEG)";
  Raise(c, JERR_NOT_COMPILED);
}
jvirt_sarray_ptr RequestVirtSarray(j_common_ptr c, int, boolean, JDIMENSION, JDIMENSION,
                                   JDIMENSION) {
  RefuseVirtual(c);
}
jvirt_barray_ptr RequestVirtBarray(j_common_ptr c, int, boolean, JDIMENSION, JDIMENSION,
                                   JDIMENSION) {
  RefuseVirtual(c);
}
void RealizeVirtArrays(j_common_ptr) {}  // none were requested
JSAMPARRAY AccessVirtSarray(j_common_ptr c, jvirt_sarray_ptr, JDIMENSION, JDIMENSION, boolean) {
  RefuseVirtual(c);
}
JBLOCKARRAY AccessVirtBarray(j_common_ptr c, jvirt_barray_ptr, JDIMENSION, JDIMENSION, boolean) {
  RefuseVirtual(c);
}

void FreePool(j_common_ptr c, int pool_id) {
  Impl* im = Of(c);
  if (pool_id == JPOOL_IMAGE) im->image.Reset();
  if (pool_id == JPOOL_PERMANENT) im->permanent.Reset();
}

void SelfDestruct(j_common_ptr) {}  // the pools belong to Impl

enum RawOutcome : int { kRawOk = 0, kRawLibjpegError, kRawWrongShape, kRawStalled };

int CreateRaw(Impl* im) {
  im->cinfo.err = &im->err.pub;
  InstallErrorHandler(&im->err);
  if (setjmp(im->err.jump) != 0) return kRawLibjpegError;
  jpeg_CreateDecompress(&im->cinfo, JPEG_LIB_VERSION, sizeof(jpeg_decompress_struct));
  return kRawOk;
}

// Decodes `n` bytes of JPEG into `out` (height rows of width * 3 bytes). Only trivial locals.
int DecodeJpegRaw(Impl* im, const unsigned char* src, std::size_t n, std::uint32_t width,
                  std::uint32_t height, std::uint8_t* out) {
  j_decompress_ptr c = &im->cinfo;
  if (setjmp(im->err.jump) != 0) {
    jpeg_abort_decompress(c);  // back to the start state; frees the image pool
    return kRawLibjpegError;
  }
  jpeg_mem_src(c, src, static_cast<unsigned long>(n));
  (void)jpeg_read_header(c, TRUE);
  im->got_width = c->image_width;
  im->got_height = c->image_height;
  im->got_components = c->num_components;
  if (c->image_width != width || c->image_height != height || c->num_components != 3) {
    jpeg_abort_decompress(c);
    return kRawWrongShape;
  }
  c->out_color_space = JCS_RGB;
  (void)jpeg_start_decompress(c);
  if (c->output_width != width || c->output_height != height || c->output_components != 3) {
    jpeg_abort_decompress(c);
    return kRawWrongShape;
  }
  const std::size_t stride = std::size_t{width} * 3;
  JSAMPROW rows[16];
  while (c->output_scanline < c->output_height) {
    const JDIMENSION first = c->output_scanline;
    const JDIMENSION want = std::min<JDIMENSION>(16, c->output_height - first);
    for (JDIMENSION k = 0; k < want; ++k) rows[k] = out + std::size_t{first + k} * stride;
    if (jpeg_read_scanlines(c, rows, want) == 0) {  // a memory source never suspends
      jpeg_abort_decompress(c);
      return kRawStalled;
    }
  }
  (void)jpeg_finish_decompress(c);
  return kRawOk;
}

struct EncodeState {
  jpeg_compress_struct cinfo{};
  JpegError err{};
  unsigned char* out = nullptr;  // malloc'd by libjpeg's memory destination
  unsigned long out_bytes = 0;
  bool created = false;
};

int EncodeJpegRaw(EncodeState* s, const std::uint8_t* rgb, std::uint32_t width,
                  std::uint32_t height, int quality) {
  j_compress_ptr c = &s->cinfo;
  c->err = &s->err.pub;
  InstallErrorHandler(&s->err);
  if (setjmp(s->err.jump) != 0) return kRawLibjpegError;
  jpeg_CreateCompress(c, JPEG_LIB_VERSION, sizeof(jpeg_compress_struct));
  s->created = true;
  jpeg_mem_dest(c, &s->out, &s->out_bytes);
  c->image_width = width;
  c->image_height = height;
  c->input_components = 3;
  c->in_color_space = JCS_RGB;
  jpeg_set_defaults(c);  // baseline, 4:2:0, standard Huffman tables, islow DCT
  jpeg_set_quality(c, quality, TRUE);
  jpeg_start_compress(c, TRUE);
  const std::size_t stride = std::size_t{width} * 3;
  while (c->next_scanline < c->image_height) {
    JSAMPROW row = const_cast<JSAMPROW>(rgb + std::size_t{c->next_scanline} * stride);
    (void)jpeg_write_scanlines(c, &row, 1);
  }
  jpeg_finish_compress(c);
  return kRawOk;
}

}  // namespace

Result<std::vector<std::byte>> EncodeJpegRgb(std::span<const std::uint8_t> rgb, std::uint32_t width,
                                             std::uint32_t height, int quality) {
  if (width == 0 || height == 0 || width > kMaxDenseSide || height > kMaxDenseSide) {
    return InvalidArgument("JPEG image " + std::to_string(width) + "x" + std::to_string(height) +
                           " is outside [1, " + std::to_string(kMaxDenseSide) + "] pixels");
  }
  if (rgb.size() != std::size_t{width} * height * 3) {
    return InvalidArgument("JPEG input of " + std::to_string(rgb.size()) + " bytes for a " +
                           std::to_string(width) + "x" + std::to_string(height) + " RGB image");
  }
  if (quality < 1 || quality > 100) {
    return InvalidArgument("JPEG quality " + std::to_string(quality) + " is outside [1, 100]");
  }
  auto state = std::make_unique<EncodeState>();
  const int rc = EncodeJpegRaw(state.get(), rgb.data(), width, height, quality);
  Result<std::vector<std::byte>> result =
      rc == kRawOk ? Result<std::vector<std::byte>>(std::vector<std::byte>(
                         reinterpret_cast<const std::byte*>(state->out),
                         reinterpret_cast<const std::byte*>(state->out) + state->out_bytes))
                   : Result<std::vector<std::byte>>(
                         Internal(std::string("JPEG encoding failed: ") + state->err.message));
  if (state->created) jpeg_destroy_compress(&state->cinfo);
  std::free(state->out);
  return result;
}

Result<DenseKeyframePayload> EncodeDenseKeyframe(KeyframeId id,
                                                 std::span<const Descriptor256> descriptors,
                                                 std::span<const float> keypoints,
                                                 const DenseKeyframeImages& images) {
  ZM_ASSIGN_OR_RETURN(std::vector<std::byte> jpeg,
                      EncodeJpegRgb(images.rgb, images.width, images.height, images.jpeg_quality));
  const std::vector<std::byte> rvl = EncodeRvlDepth(*images.depth);
  std::vector<std::byte> both(jpeg.size() + rvl.size());
  std::memcpy(both.data(), jpeg.data(), jpeg.size());
  std::memcpy(both.data() + jpeg.size(), rvl.data(), rvl.size());
  PayloadParts parts;
  parts.id = id;
  parts.descriptors = descriptors;
  parts.keypoints = keypoints;
  parts.dense_format = DenseFormat::kJpegColourRvlDepth;
  parts.dense = both;
  parts.dense_split = static_cast<std::uint32_t>(jpeg.size());
  parts.flags = kPayloadPointsFromDepth;
  parts.dense_width = images.width;
  parts.dense_height = images.height;
  parts.cloud_step = images.cloud_step;
  DenseKeyframePayload out;
  ZM_ASSIGN_OR_RETURN(out.payload, EncodePayload(parts));
  out.jpeg_bytes = static_cast<std::uint32_t>(jpeg.size());
  out.rvl_bytes = static_cast<std::uint32_t>(rvl.size());
  out.resident_bytes = static_cast<std::uint32_t>(
      DecodedLayoutFor(out.payload.size(), static_cast<std::uint32_t>(descriptors.size()),
                       images.width, images.height, images.cloud_step, /*points_from_depth=*/true)
          .end);
  return out;
}

void PointFromDepth(const CameraIntrinsics& k, const std::uint16_t* depth_mm, std::uint32_t width,
                    std::uint32_t height, float u, float v, float out[3]) {
  const double sx = static_cast<double>(width) / k.width;
  const double sy = static_cast<double>(height) / k.height;
  const double pu = std::floor(static_cast<double>(u) * sx);
  const double pv = std::floor(static_cast<double>(v) * sy);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  if (!(pu >= 0.0 && pv >= 0.0 && pu < width && pv < height)) {  // also catches NaN keypoints
    out[0] = out[1] = out[2] = nan;
    return;
  }
  const std::uint16_t mm =
      depth_mm[static_cast<std::size_t>(pv) * width + static_cast<std::size_t>(pu)];
  if (mm == 0) {
    out[0] = out[1] = out[2] = nan;
    return;
  }
  const double z = mm * 0.001;
  out[0] = static_cast<float>((static_cast<double>(u) - k.cx) / k.fx * z);
  out[1] = static_cast<float>((static_cast<double>(v) - k.cy) / k.fy * z);
  out[2] = static_cast<float>(z);
}

DenseDecoder::DenseDecoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
DenseDecoder::~DenseDecoder() = default;

Result<std::unique_ptr<DenseDecoder>> DenseDecoder::Create(const CameraIntrinsics& camera,
                                                           DenseDecoderOptions options) {
  if (options.jpeg_image_pool_bytes < 4096 || options.jpeg_permanent_pool_bytes < 4096) {
    return InvalidArgument("dense decoder pools must hold at least 4096 bytes each");
  }
  auto im = std::make_unique<Impl>();
  im->camera = camera;
  im->has_camera = camera.fx > 0.0 && camera.fy > 0.0 && camera.width > 0 && camera.height > 0;
  const std::size_t perm = RoundUp(options.jpeg_permanent_pool_bytes, kAlign);
  const std::size_t image = RoundUp(options.jpeg_image_pool_bytes, kAlign);
  im->storage = static_cast<std::byte*>(std::aligned_alloc(kAlign, perm + image));
  if (im->storage == nullptr) {
    return ResourceExhausted("cannot reserve " + std::to_string(perm + image) +
                             " bytes for the dense keyframe decoder");
  }
  im->storage_bytes = perm + image;
  im->permanent = BumpRegion{im->storage, perm};
  im->image = BumpRegion{im->storage + perm, image};
  if (CreateRaw(im.get()) != kRawOk) {
    return Internal(std::string("libjpeg could not create a decompressor: ") + im->err.message);
  }
  im->created = true;
  // Swap in our memory manager: everything libjpeg allocates from now on comes from the pools.
  im->libjpeg_mgr = im->cinfo.mem;
  jpeg_memory_mgr& m = im->mgr;
  m.alloc_small = AllocSmall;
  m.alloc_large = AllocSmall;
  m.alloc_sarray = AllocSarray;
  m.alloc_barray = AllocBarray;
  m.request_virt_sarray = RequestVirtSarray;
  m.request_virt_barray = RequestVirtBarray;
  m.realize_virt_arrays = RealizeVirtArrays;
  m.access_virt_sarray = AccessVirtSarray;
  m.access_virt_barray = AccessVirtBarray;
  m.free_pool = FreePool;
  m.self_destruct = SelfDestruct;
  m.max_memory_to_use = static_cast<long>(image);
  m.max_alloc_chunk = static_cast<long>(image);
  im->cinfo.mem = &im->mgr;
  im->cinfo.client_data = im.get();
  return std::unique_ptr<DenseDecoder>(new DenseDecoder(std::move(im)));
}

std::size_t DenseDecoder::jpeg_pool_high_water_bytes() const { return impl_->image.high; }

Status DenseDecoder::DecodeJpegRgb(std::span<const std::byte> jpeg, std::uint32_t width,
                                   std::uint32_t height, std::span<std::uint8_t> out) {
  Impl& im = *impl_;
  if (out.size() != std::size_t{width} * height * 3) {
    return InvalidArgument("JPEG output of " + std::to_string(out.size()) + " bytes for a " +
                           std::to_string(width) + "x" + std::to_string(height) + " RGB image");
  }
  if (jpeg.empty()) return Corrupt("empty JPEG stream");
  im.refusal = nullptr;
  const int rc = DecodeJpegRaw(&im, reinterpret_cast<const unsigned char*>(jpeg.data()),
                               jpeg.size(), width, height, out.data());
  switch (rc) {
    case kRawOk:
      return Status::Ok();
    case kRawWrongShape:
      return Corrupt("JPEG of " + std::to_string(jpeg.size()) + " bytes is " +
                     std::to_string(im.got_width) + "x" + std::to_string(im.got_height) + " with " +
                     std::to_string(im.got_components) + " components, expected " +
                     std::to_string(width) + "x" + std::to_string(height) + " RGB");
    case kRawStalled:
      return Corrupt("JPEG of " + std::to_string(jpeg.size()) +
                     " bytes stopped before its last row");
    default:
      break;
  }
  if (im.refusal != nullptr && std::strcmp(im.refusal, "image pool") != 0 &&
      std::strcmp(im.refusal, "permanent pool") != 0) {
    return Unsupported(std::string("JPEG of ") + std::to_string(jpeg.size()) +
                       " bytes: " + im.refusal);
  }
  if (im.refusal != nullptr) {
    const BumpRegion& p = std::strcmp(im.refusal, "image pool") == 0 ? im.image : im.permanent;
    return ResourceExhausted("JPEG " + std::to_string(width) + "x" + std::to_string(height) +
                             ": libjpeg's " + im.refusal + " of " + std::to_string(p.size) +
                             " bytes is exhausted (" + std::to_string(im.refused_bytes) +
                             " more bytes asked; raise DenseDecoderOptions)");
  }
  return Corrupt("JPEG of " + std::to_string(jpeg.size()) + " bytes: " + im.err.message);
}

Result<std::uint32_t> DenseDecoder::DecodeInSlot(std::span<std::byte> slot,
                                                 std::size_t blob_bytes) {
  Impl& im = *impl_;
  if (blob_bytes > slot.size()) {
    return InvalidArgument("payload of " + std::to_string(blob_bytes) + " bytes in a slot of " +
                           std::to_string(slot.size()));
  }
  auto view = DecodePayload(slot.first(blob_bytes), DecodeOptions{.verify_crc = false});
  if (!view.ok()) return view.status();
  const KeyframeView& v = *view;
  if (v.dense_format != DenseFormat::kJpegColourRvlDepth) return v.total_bytes;
  const auto kf = [&] { return Kf(v.id); };  // only on an error: no string when it works
  if (v.resident_bytes > slot.size()) {
    return OutOfRange(kf() + ": decoded keyframe needs " + std::to_string(v.resident_bytes) +
                      " bytes (blob of " + std::to_string(v.total_bytes) +
                      " + colour, depth, points, cloud " + std::to_string(v.dense_width) + "x" +
                      std::to_string(v.dense_height) + "), larger than the arena slot of " +
                      std::to_string(slot.size()) + " bytes");
  }
  const bool from_depth = (v.flags & kPayloadPointsFromDepth) != 0;
  if (from_depth && v.feature_count > 0 && !im.has_camera) {
    return FailedPrecondition(kf() + ": the map has no camera intrinsics to turn depth into its " +
                              std::to_string(v.feature_count) + " feature points");
  }
  const std::uint32_t w = v.dense_width, h = v.dense_height;
  const std::size_t pixels = std::size_t{w} * h;
  const DecodedLayout d =
      DecodedLayoutFor(v.total_bytes, v.feature_count, w, h, v.cloud_step, from_depth);
  std::byte* base = slot.data();
  auto* colour = reinterpret_cast<std::uint8_t*>(base + d.colour);
  auto* depth = reinterpret_cast<std::uint16_t*>(base + d.depth);

  Status s = DecodeJpegRgb(v.dense.first(v.dense_split), w, h,
                           std::span<std::uint8_t>(colour, pixels * 3));
  if (!s.ok()) return s.Annotate(kf() + ": colour");
  s = DecodeRvlDepthInto(v.dense.subspan(v.dense_split), w, h,
                         std::span<std::uint16_t>(depth, pixels));
  if (!s.ok()) return s.Annotate(kf() + ": depth");

  if (from_depth) {
    auto* points = reinterpret_cast<float*>(base + d.points);
    for (std::uint32_t i = 0; i < v.feature_count; ++i) {
      PointFromDepth(im.camera, depth, w, h, v.keypoints[2 * i], v.keypoints[2 * i + 1],
                     points + 3 * i);
    }
  }
  if (d.cloud_points > 0) {
    // The depth image's pinhole: the keypoint camera scaled to the dense resolution (same field
    // of view); without a camera, a centred 90-degree one (the cloud is for display only).
    const double sx = im.has_camera ? static_cast<double>(w) / im.camera.width : 1.0;
    const double sy = im.has_camera ? static_cast<double>(h) / im.camera.height : 1.0;
    const double fx = im.has_camera ? im.camera.fx * sx : w / 2.0;
    const double fy = im.has_camera ? im.camera.fy * sy : w / 2.0;
    const double cx = im.has_camera ? im.camera.cx * sx : w / 2.0;
    const double cy = im.has_camera ? im.camera.cy * sy : h / 2.0;
    const std::uint32_t step = v.cloud_step;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    auto* cloud = reinterpret_cast<float*>(base + d.cloud);
    // (w / step) x (h / step) points, as DecodedLayoutFor counted: the pixels at multiples of
    // the step, the last partial block of a side left out.
    const std::uint32_t rows = h / step, cols = w / step;
    for (std::uint32_t r = 0; r < rows; ++r) {
      const std::uint32_t y = r * step;
      const double yn = (y + 0.5 - cy) / fy;
      for (std::uint32_t c = 0; c < cols; ++c, cloud += 4) {
        const std::uint32_t x = c * step;
        const std::size_t p = std::size_t{y} * w + x;
        const std::uint8_t* rgb = colour + 3 * p;
        const std::uint32_t packed =
            (std::uint32_t{rgb[0]} << 16) | (std::uint32_t{rgb[1]} << 8) | rgb[2];
        std::memcpy(cloud + 3, &packed, sizeof packed);
        if (depth[p] == 0) {
          cloud[0] = cloud[1] = cloud[2] = nan;
          continue;
        }
        const double z = depth[p] * 0.001;
        cloud[0] = static_cast<float>((x + 0.5 - cx) / fx * z);
        cloud[1] = static_cast<float>(yn * z);
        cloud[2] = static_cast<float>(z);
      }
    }
  }
  PayloadHeader header;
  std::memcpy(&header, base, sizeof header);
  header.flags |= kPayloadDecoded;
  std::memcpy(base, &header, sizeof header);
  return v.resident_bytes;
}

}  // namespace zm
