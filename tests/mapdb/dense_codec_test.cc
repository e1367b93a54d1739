// Dense keyframes (lib/mapdb/dense_codec.h): JPEG and RVL round trips, the decoded layout in a
// slot (colour, depth, points from depth, cloud, all 16-byte aligned and exposed without copies),
// a warm decode that allocates nothing (operator new AND malloc counted), every kind of damaged
// compressed data refused with the keyframe named and nothing written outside the slot, and the
// load path through MapDb: slots hold the resident size the metadata reports, a damaged blob
// releases its slot.
#include "mapdb/dense_codec.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <span>
#include <vector>

#include "mapdb/rvl.h"
#include "mapdb_test_util.h"
#include "support/counting_allocator.h"
#include "support/malloc_probe.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;

constexpr CameraIntrinsics kCamera{320.0, 320.0, 320.0, 240.0, 640, 480};

struct DenseParts {
  std::uint32_t width = 64, height = 48, step = 4;
  std::vector<std::uint8_t> rgb;
  DepthImage16 depth;
  std::vector<Descriptor256> desc;
  std::vector<float> kps;
  std::vector<std::byte> jpeg, rvl;
};

// A smooth colour image, a tilted depth plane with a hole in the top-left corner, and keypoints
// on the plane, in the hole and outside the image.
DenseParts MakeParts(std::uint32_t width = 64, std::uint32_t height = 48) {
  DenseParts p;
  p.width = width;
  p.height = height;
  p.rgb.resize(std::size_t{width} * height * 3);
  p.depth.width = width;
  p.depth.height = height;
  p.depth.pixels.resize(std::size_t{width} * height);
  for (std::uint32_t y = 0; y < height; ++y) {
    for (std::uint32_t x = 0; x < width; ++x) {
      const std::size_t i = std::size_t{y} * width + x;
      p.rgb[3 * i] = static_cast<std::uint8_t>(x * 255 / width);
      p.rgb[3 * i + 1] = static_cast<std::uint8_t>(y * 255 / height);
      p.rgb[3 * i + 2] = 128;
      const bool hole = x < width / 8 && y < height / 8;
      p.depth.pixels[i] = hole ? 0 : static_cast<std::uint16_t>(1500 + 10 * x + 5 * y);
    }
  }
  // Keypoints in the 640x480 keypoint image: on the plane, in the hole, outside.
  const float uv[][2] = {
      {320.5f, 240.5f}, {100.2f, 400.7f}, {600.0f, 30.0f}, {5.0f, 5.0f}, {700.0f, 10.0f}};
  for (const auto& k : uv) {
    Descriptor256 d{};
    d[0] = static_cast<std::uint8_t>(p.desc.size());
    p.desc.push_back(d);
    p.kps.push_back(k[0]);
    p.kps.push_back(k[1]);
  }
  auto jpeg = EncodeJpegRgb(p.rgb, width, height, 95);
  REQUIRE(jpeg.ok());
  p.jpeg = std::move(jpeg).value();
  p.rvl = EncodeRvlDepth(p.depth);
  return p;
}

std::vector<std::byte> Payload(const DenseParts& p, std::int64_t id,
                               std::span<const std::byte> jpeg, std::span<const std::byte> rvl) {
  std::vector<std::byte> dense(jpeg.begin(), jpeg.end());
  dense.insert(dense.end(), rvl.begin(), rvl.end());
  PayloadParts parts;
  parts.id = KeyframeId{id};
  parts.descriptors = p.desc;
  parts.keypoints = p.kps;
  parts.dense_format = DenseFormat::kJpegColourRvlDepth;
  parts.dense = dense;
  parts.dense_split = static_cast<std::uint32_t>(jpeg.size());
  parts.flags = kPayloadPointsFromDepth;
  parts.dense_width = p.width;
  parts.dense_height = p.height;
  parts.cloud_step = p.step;
  auto blob = EncodePayload(parts);
  REQUIRE_MESSAGE(blob.ok(), blob.status().ToString());
  return std::move(blob).value();
}

std::vector<std::byte> Payload(const DenseParts& p, std::int64_t id = 7) {
  return Payload(p, id, p.jpeg, p.rvl);
}

// A slot of `bytes` (64-byte aligned) between two guard bands; free bytes are 0xA5.
class GuardedSlot {
 public:
  explicit GuardedSlot(std::size_t bytes) : bytes_(bytes), buffer_(kGuard + bytes + kGuard + 64) {
    const auto addr = reinterpret_cast<std::uintptr_t>(buffer_.data()) + kGuard;
    offset_ = kGuard + ((64 - addr % 64) % 64);
    std::memset(buffer_.data(), 0x5A, buffer_.size());
    std::memset(buffer_.data() + offset_, 0xA5, bytes_);
  }
  std::span<std::byte> slot() { return {buffer_.data() + offset_, bytes_}; }
  void Load(std::span<const std::byte> blob) {
    std::memcpy(buffer_.data() + offset_, blob.data(), blob.size());
  }
  // The guard bands and every slot byte from `from` on still hold what they were filled with.
  [[nodiscard]] bool UntouchedOutside(std::size_t from) const {
    for (std::size_t i = 0; i < offset_; ++i) {
      if (buffer_[i] != std::byte{0x5A}) return false;
    }
    for (std::size_t i = offset_ + from; i < offset_ + bytes_; ++i) {
      if (buffer_[i] != std::byte{0xA5}) return false;
    }
    for (std::size_t i = offset_ + bytes_; i < buffer_.size(); ++i) {
      if (buffer_[i] != std::byte{0x5A}) return false;
    }
    return true;
  }

 private:
  static constexpr std::size_t kGuard = 256;
  std::size_t bytes_;
  std::vector<std::byte> buffer_;
  std::size_t offset_ = 0;
};

std::uint32_t ResidentOf(std::span<const std::byte> blob) {
  auto v = DecodePayload(blob);
  REQUIRE(v.ok());
  return v->resident_bytes;
}

TEST_CASE("JPEG colour round trips through libjpeg-turbo and our memory manager") {
  const DenseParts p = MakeParts(80, 60);
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  std::vector<std::uint8_t> out(p.rgb.size());
  REQUIRE((*decoder)->DecodeJpegRgb(p.jpeg, 80, 60, out).ok());
  double error = 0.0;
  for (std::size_t i = 0; i < out.size(); ++i) error += std::abs(int{out[i]} - int{p.rgb[i]});
  CHECK(error / static_cast<double>(out.size()) < 3.0);  // q95 on a smooth image
  // Another size is refused, with both sizes named.
  std::vector<std::uint8_t> other(64 * 48 * 3);
  const Status wrong = (*decoder)->DecodeJpegRgb(p.jpeg, 64, 48, other);
  CHECK(wrong.code() == StatusCode::kCorrupt);
  CHECK(Contains(wrong, "80x60"));
  CHECK(EncodeJpegRgb(p.rgb, 80, 60, 0).status().code() == StatusCode::kInvalidArgument);
  CHECK(EncodeJpegRgb(std::span(p.rgb).first(10), 80, 60, 90).status().code() ==
        StatusCode::kInvalidArgument);
}

TEST_CASE("RVL decodes into a caller's buffer and checks the image size") {
  const DenseParts p = MakeParts();
  std::vector<std::uint16_t> out(p.depth.pixels.size(), 0xBEEF);
  REQUIRE(DecodeRvlDepthInto(p.rvl, p.width, p.height, out).ok());
  CHECK(out == p.depth.pixels);  // lossless, zeros written too
  CHECK(DecodeRvlDepthInto(p.rvl, 32, 48, std::span(out).first(32 * 48)).code() ==
        StatusCode::kCorrupt);
  CHECK(DecodeRvlDepthInto(p.rvl, p.width, p.height, std::span(out).first(10)).code() ==
        StatusCode::kInvalidArgument);
}

TEST_CASE("a dense payload decodes into its slot: colour, depth, points from depth, cloud") {
  const DenseParts p = MakeParts();
  const std::vector<std::byte> blob = Payload(p);
  const std::uint32_t resident = ResidentOf(blob);
  // Not decoded yet: no points, no images (a localizer would skip it).
  auto before = DecodePayload(blob);
  REQUIRE(before.ok());
  CHECK(before->points == nullptr);
  CHECK(before->points_frame == PointFrame::kCamera);
  CHECK(before->colour == nullptr);
  CHECK(blob.size() ==
        PayloadSize(5, static_cast<std::uint32_t>(p.jpeg.size() + p.rvl.size()), false));

  GuardedSlot slot(resident + 1000);
  slot.Load(blob);
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  auto landed = (*decoder)->DecodeInSlot(slot.slot(), blob.size());
  REQUIRE_MESSAGE(landed.ok(), landed.status().ToString());
  CHECK(*landed == resident);
  CHECK(slot.UntouchedOutside(resident));

  auto v = DecodePayload(slot.slot(), {}, /*blob_is_slot=*/true);
  REQUIRE_MESSAGE(v.ok(), v.status().ToString());
  CHECK(v->decoded());
  CHECK(v->resident_bytes == resident);
  for (const void* ptr :
       {static_cast<const void*>(v->descriptors), static_cast<const void*>(v->points),
        static_cast<const void*>(v->keypoints), static_cast<const void*>(v->colour),
        static_cast<const void*>(v->depth), static_cast<const void*>(v->cloud)}) {
    REQUIRE(ptr != nullptr);
    CHECK(reinterpret_cast<std::uintptr_t>(ptr) % 16 == 0);
    // Views into the slot, not copies.
    CHECK(static_cast<const std::byte*>(ptr) >= slot.slot().data());
    CHECK(static_cast<const std::byte*>(ptr) < slot.slot().data() + resident);
  }
  CHECK(std::memcmp(v->depth, p.depth.pixels.data(), p.depth.pixels.size() * 2) == 0);
  double colour_error = 0.0;
  for (std::size_t i = 0; i < p.rgb.size(); ++i)
    colour_error += std::abs(int{v->colour[i]} - int{p.rgb[i]});
  CHECK(colour_error / static_cast<double>(p.rgb.size()) < 3.0);

  // Points: the depth at the keypoint's pixel, back-projected with the keypoint camera.
  for (std::uint32_t i = 0; i < 5; ++i) {
    const double u = p.kps[2 * i], vv = p.kps[2 * i + 1];
    const float* pt = v->points + 3 * i;
    const auto px = static_cast<std::uint32_t>(u * 64 / 640),
               py = static_cast<std::uint32_t>(vv * 48 / 480);
    if (px >= 64 || py >= 48 || p.depth.pixels[py * 64 + px] == 0) {
      CHECK(std::isnan(pt[0]));  // outside the image or in the hole: no 3-D point
      CHECK(std::isnan(pt[2]));
      continue;
    }
    const double z = p.depth.pixels[py * 64 + px] * 0.001;
    CHECK(pt[2] == doctest::Approx(z).epsilon(1e-6));
    CHECK(pt[0] == doctest::Approx((u - 320.0) / 320.0 * z).epsilon(1e-5));
    CHECK(pt[1] == doctest::Approx((vv - 240.0) / 320.0 * z).epsilon(1e-5));
  }
  CHECK(std::isfinite(v->points[0]));  // the first keypoint is on the plane
  // The cloud: every 4th pixel, x y z in the depth camera and the decoded colour.
  REQUIRE(v->cloud_points == 16 * 12);
  for (std::uint32_t cy = 0; cy < 12; ++cy) {
    for (std::uint32_t cx = 0; cx < 16; ++cx) {
      const float* c = v->cloud + 4 * (cy * 16 + cx);
      const std::uint32_t x = 4 * cx, y = 4 * cy;
      const std::size_t i = std::size_t{y} * 64 + x;
      std::uint32_t packed;
      std::memcpy(&packed, c + 3, 4);
      CHECK(packed == ((std::uint32_t{v->colour[3 * i]} << 16) |
                       (std::uint32_t{v->colour[3 * i + 1]} << 8) | v->colour[3 * i + 2]));
      if (p.depth.pixels[i] == 0) {
        CHECK(std::isnan(c[2]));
      } else {
        CHECK(c[2] == doctest::Approx(p.depth.pixels[i] * 0.001));
        CHECK(c[0] ==
              doctest::Approx((x + 0.5 - 32.0) / 32.0 * p.depth.pixels[i] * 0.001).epsilon(1e-5));
      }
    }
  }
}

TEST_CASE("a cloud step that does not divide the image takes whole blocks only") {
  DenseParts p = MakeParts();  // 64 x 48
  p.step = 5;                  // 12 x 9 points; the last 4 columns and 3 rows are left out
  const std::vector<std::byte> blob = Payload(p, 9);
  const std::uint32_t resident = ResidentOf(blob);
  GuardedSlot slot(resident);  // exactly: a point too many would hit the guard
  slot.Load(blob);
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  auto landed = (*decoder)->DecodeInSlot(slot.slot(), blob.size());
  REQUIRE(landed.ok());
  CHECK(slot.UntouchedOutside(resident));
  auto v = DecodePayload(slot.slot(), {}, true);
  REQUIRE(v.ok());
  CHECK(v->cloud_points == 12 * 9);
  const float* last = v->cloud + 4 * (12 * 9 - 1);  // pixel (55, 40)
  CHECK(last[2] == doctest::Approx(p.depth.pixels[40 * 64 + 55] * 0.001));
}

TEST_CASE("a warm decode allocates nothing: operator new and malloc counted") {
  const DenseParts small = MakeParts();
  const DenseParts big = MakeParts(640, 480);
  const std::vector<std::byte> blobs[] = {Payload(small, 1), Payload(big, 2)};
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  GuardedSlot slot(ResidentOf(blobs[1]) + 64);
  for (const auto& blob : blobs) {  // warm-up: libjpeg's tables land in the permanent pool
    slot.Load(blob);
    REQUIRE((*decoder)->DecodeInSlot(slot.slot(), blob.size()).ok());
  }
  for (int round = 0; round < 3; ++round) {
    for (const auto& blob : blobs) {
      slot.Load(blob);
      test::AllocationCounter allocs;
      test::MallocProbe mallocs;
      auto landed = (*decoder)->DecodeInSlot(slot.slot(), blob.size());
      CHECK(allocs.allocations() == 0);
      CHECK(mallocs.count() == 0);
      REQUIRE(landed.ok());
    }
  }
  // libjpeg's working memory for a 640-pixel-wide image sits well inside the default pool.
  CHECK((*decoder)->jpeg_pool_high_water_bytes() > 0);
  CHECK((*decoder)->jpeg_pool_high_water_bytes() < DenseDecoderOptions{}.jpeg_image_pool_bytes / 4);
  MESSAGE("libjpeg image pool high water for 640x480: ", (*decoder)->jpeg_pool_high_water_bytes(),
          " bytes");
}

TEST_CASE("the largest dense image fits libjpeg's default pool") {
  const std::uint32_t w = kMaxDenseSide, h = 64;  // a wide strip: the pool scales with width
  std::vector<std::uint8_t> rgb(std::size_t{w} * h * 3, 100);
  auto jpeg = EncodeJpegRgb(rgb, w, h, 90);
  REQUIRE(jpeg.ok());
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  std::vector<std::uint8_t> out(rgb.size());
  const Status s = (*decoder)->DecodeJpegRgb(*jpeg, w, h, out);
  CHECK_MESSAGE(s.ok(), s.ToString());
  MESSAGE("libjpeg image pool high water for ", w,
          " columns: ", (*decoder)->jpeg_pool_high_water_bytes(), " bytes");
  // A pool too small is an error naming it, not a crash or a heap fallback.
  auto tiny = DenseDecoder::Create(kCamera, {.jpeg_image_pool_bytes = 4096});
  REQUIRE(tiny.ok());
  const Status refused = (*tiny)->DecodeJpegRgb(*jpeg, w, h, out);
  CHECK(refused.code() == StatusCode::kResourceExhausted);
  CHECK(Contains(refused, "image pool"));
}

TEST_CASE("damaged compressed data is refused with the keyframe named, nothing written outside") {
  const DenseParts p = MakeParts();
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  const auto bytes = [](std::span<const std::byte> s, std::size_t n) { return s.first(n); };
  std::vector<std::byte> garbage(p.jpeg.size());
  for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<std::byte>(i * 37 + 11);
  const DenseParts other_size = MakeParts(32, 24);
  std::vector<std::uint8_t> progressive_bytes;
  {
    cv::Mat img(48, 64, CV_8UC3, const_cast<std::uint8_t*>(p.rgb.data()));
    REQUIRE(cv::imencode(".jpg", img, progressive_bytes, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  }
  const std::vector<std::byte> progressive(
      reinterpret_cast<const std::byte*>(progressive_bytes.data()),
      reinterpret_cast<const std::byte*>(progressive_bytes.data()) + progressive_bytes.size());
  DepthImage16 other_depth = other_size.depth;
  const std::vector<std::byte> other_rvl = EncodeRvlDepth(other_depth);

  struct Case {
    const char* name;
    std::vector<std::byte> blob;
    StatusCode code;
    const char* says;
  };
  const Case cases[] = {
      {"truncated JPEG", Payload(p, 11, bytes(p.jpeg, p.jpeg.size() / 2), p.rvl),
       StatusCode::kCorrupt, "colour"},
      {"not a JPEG", Payload(p, 12, garbage, p.rvl), StatusCode::kCorrupt, "colour"},
      {"JPEG of another size", Payload(p, 13, other_size.jpeg, p.rvl), StatusCode::kCorrupt,
       "32x24"},
      {"progressive JPEG", Payload(p, 14, progressive, p.rvl), StatusCode::kUnsupported,
       "progressive"},
      {"truncated RVL", Payload(p, 15, p.jpeg, bytes(p.rvl, p.rvl.size() / 2)),
       StatusCode::kCorrupt, "depth"},
      {"RVL of another size", Payload(p, 16, p.jpeg, other_rvl), StatusCode::kCorrupt, "32x24"},
      {"RVL header only", Payload(p, 17, p.jpeg, bytes(p.rvl, 8)), StatusCode::kCorrupt,
       "DEPTHRVL"},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    const std::uint32_t resident = ResidentOf(c.blob);
    GuardedSlot slot(resident + 512);
    slot.Load(c.blob);
    auto landed = (*decoder)->DecodeInSlot(slot.slot(), c.blob.size());
    REQUIRE_FALSE(landed.ok());
    CHECK(landed.status().code() == c.code);
    CHECK_MESSAGE(Contains(landed.status(), "keyframe 1"), landed.status().ToString());  // 11..17
    CHECK_MESSAGE(Contains(landed.status(), c.says), landed.status().ToString());
    CHECK(slot.UntouchedOutside(resident));
    auto v = DecodePayload(slot.slot(), {}, true);
    REQUIRE(v.ok());
    CHECK_FALSE(v->decoded());  // never marked decoded
  }
  // The decoder is still good after every failure.
  const std::vector<std::byte> good = Payload(p, 18);
  GuardedSlot slot(ResidentOf(good));
  slot.Load(good);
  CHECK((*decoder)->DecodeInSlot(slot.slot(), good.size()).ok());
}

TEST_CASE("a slot smaller than the resident size is refused before anything is decoded") {
  const DenseParts p = MakeParts();
  const std::vector<std::byte> blob = Payload(p, 21);
  const std::uint32_t resident = ResidentOf(blob);
  GuardedSlot slot(resident - 16);
  slot.Load(blob);
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  auto landed = (*decoder)->DecodeInSlot(slot.slot(), blob.size());
  REQUIRE_FALSE(landed.ok());
  CHECK(landed.status().code() == StatusCode::kOutOfRange);
  CHECK(Contains(landed.status(), "keyframe 21"));
  CHECK(Contains(landed.status(), std::to_string(resident)));
  CHECK(slot.UntouchedOutside(blob.size()));
  // Without camera intrinsics the points cannot be made: a clear error, not garbage points.
  auto blind = DenseDecoder::Create(CameraIntrinsics{});
  REQUIRE(blind.ok());
  GuardedSlot roomy(resident);
  roomy.Load(blob);
  CHECK((*blind)->DecodeInSlot(roomy.slot(), blob.size()).status().code() ==
        StatusCode::kFailedPrecondition);
}

TEST_CASE("payloads that do not decode pass through untouched") {
  const std::vector<std::byte> blob = test::MakePayload(3, 10, 300);
  GuardedSlot slot(blob.size() + 256);
  slot.Load(blob);
  auto decoder = DenseDecoder::Create(kCamera);
  REQUIRE(decoder.ok());
  auto landed = (*decoder)->DecodeInSlot(slot.slot(), blob.size());
  REQUIRE(landed.ok());
  CHECK(*landed == blob.size());
  CHECK(slot.UntouchedOutside(blob.size()));
}

// A map of dense keyframes through the real load path.
struct DenseMap {
  std::vector<std::vector<std::byte>> blobs;
  std::uint32_t largest_resident = 0;
};

DenseMap BuildDenseMap(const std::string& path, std::int64_t damaged_id = 0) {
  DenseMap m;
  auto w = MapDbWriter::Create(path);
  REQUIRE(w.ok());
  REQUIRE((*w)->SetCamera(kCamera).ok());
  std::vector<KeyframeRecord> recs;
  const DenseParts p = MakeParts();
  for (std::int64_t id = 1; id <= 6; ++id) {
    // Sizes differ: a slightly different colour image per keyframe.
    DenseParts q = p;
    q.rgb[0] = static_cast<std::uint8_t>(id * 40);
    auto jpeg = EncodeJpegRgb(q.rgb, q.width, q.height, 60 + 5 * static_cast<int>(id));
    REQUIRE(jpeg.ok());
    std::vector<std::byte> j = std::move(jpeg).value();
    if (id == damaged_id) {
      for (std::size_t i = j.size() / 3; i < j.size(); ++i)
        j[i] = std::byte{0};  // CRC still matches
    }
    m.blobs.push_back(Payload(q, id, j, q.rvl));
    m.largest_resident = std::max(m.largest_resident, ResidentOf(m.blobs.back()));
  }
  for (std::int64_t id = 1; id <= 6; ++id) {
    KeyframeMeta meta;
    meta.id = KeyframeId{id};
    meta.pose = PoseFromXYYaw(static_cast<double>(id), 0.0, 0.0);
    recs.push_back({meta, m.blobs[static_cast<std::size_t>(id - 1)]});
  }
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  ZoneRecord z;
  z.id = ZoneId{0};
  z.name = "ward";
  z.kind = "ward";
  z.polygon = {{0.0, 0.0}, {10.0, 0.0}, {10.0, 10.0}};
  std::vector<ZoneMember> members;
  for (std::int64_t id = 1; id <= 6; ++id) members.push_back({ZoneId{0}, KeyframeId{id}});
  REQUIRE((*w)->ReplaceZones(std::vector<ZoneRecord>{z}, members).ok());
  REQUIRE((*w)->Finish().ok());
  return m;
}

TEST_CASE("through MapDb: slots are sized by the resident footprint and hold decoded keyframes") {
  test::TempDir dir;
  const std::string path = dir.File("dense.db");
  const DenseMap built = BuildDenseMap(path);
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  // The metadata reports the largest RESIDENT keyframe (K_max = budget / slot is then right).
  CHECK((*db)->metadata().largest_payload_bytes == built.largest_resident);
  auto kfs = (*db)->Keyframes();
  REQUIRE(kfs.ok());
  for (const KeyframeMeta& k : *kfs) {
    CHECK(k.payload_bytes == ResidentOf(built.blobs[static_cast<std::size_t>(k.id.value - 1)]));
    CHECK(k.payload_bytes > built.blobs[static_cast<std::size_t>(k.id.value - 1)].size());
  }
  Arena arena = test::MakeArena(8, (*db)->metadata().largest_payload_bytes);
  test::RecordingSink sink;
  auto st = (*db)->LoadZone(ZoneId{0}, arena, sink);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  REQUIRE(sink.loaded().size() == 6);
  std::uint64_t blob_bytes = 0;
  for (const auto& e : sink.loaded()) {
    const auto& blob = built.blobs[static_cast<std::size_t>(e.id.value - 1)];
    blob_bytes += blob.size();
    CHECK(e.bytes == ResidentOf(blob));  // the sink is told the resident size
    auto v = DecodePayload(arena.Slot(e.slot), {.verify_crc = false}, true);
    REQUIRE(v.ok());
    CHECK(v->decoded());
    CHECK(std::isfinite(v->points[0]));
  }
  CHECK(st->bytes == blob_bytes);  // bytes read from the database stay the compressed ones
  for (const auto& e : sink.loaded()) arena.Release(e.slot);
  sink.Clear();
  const std::vector<KeyframeId> ids = {KeyframeId{2}, KeyframeId{5}};
  auto per = (*db)->LoadKeyframes(ids, arena, sink);
  REQUIRE(per.ok());
  for (const auto& e : sink.loaded()) {
    auto v = DecodePayload(arena.Slot(e.slot), {.verify_crc = false}, true);
    REQUIRE(v.ok());
    CHECK(v->decoded());
    arena.Release(e.slot);
  }
}

TEST_CASE("through MapDb: a time-sliced zone load delivers each keyframe decoded") {
  test::TempDir dir;
  const std::string path = dir.File("sliced.db");
  BuildDenseMap(path);
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  Arena arena = test::MakeArena(8, (*db)->metadata().largest_payload_bytes);
  test::RecordingSink sink;
  REQUIRE((*db)->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
  bool done = false;
  for (int steps = 0; !done && steps < 20; ++steps) {
    auto step = (*db)->StepZoneLoad(LoadBudget{.max_keyframes = 1});
    REQUIRE_MESSAGE(step.ok(), step.status().ToString());
    done = step->done;
    // Whatever has landed so far is complete: usable keyframe by keyframe.
    for (const auto& e : sink.loaded()) {
      auto v = DecodePayload(arena.Slot(e.slot), {.verify_crc = false}, true);
      REQUIRE(v.ok());
      CHECK(v->decoded());
    }
  }
  CHECK(done);
  CHECK(sink.loaded().size() == 6);
}

TEST_CASE("through MapDb: a damaged dense blob stops the load naming it and releases its slot") {
  test::TempDir dir;
  const std::string path = dir.File("damaged.db");
  BuildDenseMap(path, /*damaged_id=*/4);
  for (bool verify : {true, false}) {  // the damage is inside a valid blob: CRC cannot see it
    auto db = MapDb::Open(path, {.verify_checksums = verify});
    REQUIRE(db.ok());
    Arena arena = test::MakeArena(8, (*db)->metadata().largest_payload_bytes);
    test::RecordingSink sink;
    auto st = (*db)->LoadZone(ZoneId{0}, arena, sink);
    REQUIRE_FALSE(st.ok());
    CHECK(st.status().code() == StatusCode::kCorrupt);
    CHECK_MESSAGE(Contains(st.status(), "keyframe 4"), st.status().ToString());
    CHECK(Contains(st.status(), "colour"));
    CHECK(sink.loaded().size() == 3);  // 1..3 landed before it
    CHECK(arena.in_use() == 3);        // keyframe 4's slot was handed back
    for (const auto& e : sink.loaded()) arena.Release(e.slot);
    const std::vector<KeyframeId> ids = {KeyframeId{4}};
    auto per = (*db)->LoadKeyframes(ids, arena, sink);
    CHECK(per.status().code() == StatusCode::kCorrupt);
    CHECK(arena.in_use() == 0);
  }
}

}  // namespace
}  // namespace zm
