// Frames file writer and reader (format in frames_file.h). Byte order is the host's, which must
// be little-endian (x86-64 and aarch64 both are); a static_assert guards it.
#include "runtime/frames_file.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace zm {
namespace {

static_assert(std::endian::native == std::endian::little, "frames files are little-endian");

template <class T>
void Put(std::uint8_t* buf, std::size_t at, T value) {
  std::memcpy(buf + at, &value, sizeof(T));
}
template <class T>
T Get(const std::uint8_t* buf, std::size_t at) {
  T value;
  std::memcpy(&value, buf + at, sizeof(T));
  return value;
}

// Header field offsets.
constexpr std::size_t kOffMagic = 0, kOffVersion = 4, kOffHeaderBytes = 6, kOffCount = 8,
                      kOffMaxFeatures = 16, kOffFx = 24, kOffFy = 32, kOffCx = 40, kOffCy = 48,
                      kOffWidth = 56, kOffHeight = 60, kOffRate = 64, kOffMaxColour = 72,
                      kOffImageWidth = 76, kOffImageHeight = 80;
constexpr std::size_t kOffRecordColourBytes = 76;

void EncodeHeader(const FramesFileInfo& info, std::uint8_t* buf) {
  std::memset(buf, 0, kFramesHeaderBytes);
  Put<std::uint32_t>(buf, kOffMagic, kFramesMagic);
  Put<std::uint16_t>(buf, kOffVersion, kFramesVersion);
  Put<std::uint16_t>(buf, kOffHeaderBytes, static_cast<std::uint16_t>(kFramesHeaderBytes));
  Put<std::uint64_t>(buf, kOffCount, info.frame_count);
  Put<std::uint32_t>(buf, kOffMaxFeatures, info.max_features);
  Put<double>(buf, kOffFx, info.camera.fx);
  Put<double>(buf, kOffFy, info.camera.fy);
  Put<double>(buf, kOffCx, info.camera.cx);
  Put<double>(buf, kOffCy, info.camera.cy);
  Put<std::uint32_t>(buf, kOffWidth, info.camera.width);
  Put<std::uint32_t>(buf, kOffHeight, info.camera.height);
  Put<double>(buf, kOffRate, info.rate_hz);
  Put<std::uint32_t>(buf, kOffMaxColour, info.max_colour_bytes);
  Put<std::uint32_t>(buf, kOffImageWidth, info.max_colour_bytes > 0 ? info.image_width : 0);
  Put<std::uint32_t>(buf, kOffImageHeight, info.max_colour_bytes > 0 ? info.image_height : 0);
}

}  // namespace

Result<FrameWriter> FrameWriter::Create(const std::string& path, const CameraIntrinsics& camera,
                                        double rate_hz) {
  FrameWriter w;
  w.file_.reset(std::fopen(path.c_str(), "wb"));
  if (!w.file_) return IoError("cannot create frames file " + path);
  w.path_ = path;
  w.info_.camera = camera;
  w.info_.rate_hz = rate_hz;
  w.info_.image_width = camera.width;
  w.info_.image_height = camera.height;
  std::uint8_t header[kFramesHeaderBytes];
  EncodeHeader(w.info_, header);
  if (std::fwrite(header, 1, sizeof(header), w.file_.get()) != sizeof(header)) {
    return IoError("cannot write the header of " + path);
  }
  return w;
}

Status FrameWriter::Append(const Frame& frame) {
  if (!file_) return FailedPrecondition("frames file " + path_ + " is already finished");
  const std::uint32_t n = frame.feature_count();
  if (frame.index != info_.frame_count) {
    return InvalidArgument("frames file " + path_ + ": frame index " +
                           std::to_string(frame.index) + " appended as frame " +
                           std::to_string(info_.frame_count));
  }
  if (frame.keypoints.size() != 2 * std::size_t{n}) {
    return InvalidArgument("frames file " + path_ + ": frame " + std::to_string(frame.index) +
                           " has " + std::to_string(frame.keypoints.size()) +
                           " keypoint floats for " + std::to_string(n) + " features");
  }
  if (n > kMaxFeaturesPerKeyframe) {
    return OutOfRange("frames file " + path_ + ": frame " + std::to_string(frame.index) +
                      " has " + std::to_string(n) + " features, limit " +
                      std::to_string(kMaxFeaturesPerKeyframe));
  }
  if (info_.frame_count > 0 && frame.stamp_s < last_stamp_s_) {
    return InvalidArgument("frames file " + path_ + ": frame " + std::to_string(frame.index) +
                           " goes back in time");
  }
  std::uint32_t colour_bytes = 0;
  if (frame.has_image()) {
    if (frame.colour_codec != ImageCodec::kJpeg) {
      return InvalidArgument("frames file " + path_ + ": frame " + std::to_string(frame.index) +
                             " has a colour image that is not JPEG");
    }
    if (frame.colour.empty() || frame.colour.size() > kMaxFrameColourBytes) {
      return InvalidArgument("frames file " + path_ + ": frame " + std::to_string(frame.index) +
                             " has a colour image of " + std::to_string(frame.colour.size()) +
                             " bytes, outside [1, " + std::to_string(kMaxFrameColourBytes) + "]");
    }
    colour_bytes = static_cast<std::uint32_t>(frame.colour.size());
  }
  std::uint8_t rec[kFrameRecordHeaderBytes] = {};
  Put<std::uint64_t>(rec, 0, frame.index);
  Put<double>(rec, 8, frame.stamp_s);
  const Eigen::Vector3d t = frame.odom.translation();
  const Eigen::Quaterniond q(frame.odom.linear());
  const double pose[7] = {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
  for (std::size_t i = 0; i < 7; ++i) Put<double>(rec, 16 + 8 * i, pose[i]);
  Put<std::uint32_t>(rec, 72, n);
  Put<std::uint32_t>(rec, kOffRecordColourBytes, colour_bytes);
  std::FILE* f = file_.get();
  bool ok = std::fwrite(rec, 1, sizeof(rec), f) == sizeof(rec);
  if (n > 0) {
    ok = ok && std::fwrite(frame.descriptors.data(), kDescriptorBytes, n, f) == n;
    ok = ok && std::fwrite(frame.keypoints.data(), sizeof(float), 2 * std::size_t{n}, f) ==
                   2 * std::size_t{n};
  }
  if (colour_bytes > 0) ok = ok && std::fwrite(frame.colour.data(), 1, colour_bytes, f) == colour_bytes;
  if (!ok) return IoError("cannot write frame " + std::to_string(frame.index) + " to " + path_);
  ++info_.frame_count;
  if (n > info_.max_features) info_.max_features = n;
  if (colour_bytes > info_.max_colour_bytes) info_.max_colour_bytes = colour_bytes;
  last_stamp_s_ = frame.stamp_s;
  return Status::Ok();
}

Status FrameWriter::Finish() {
  if (!file_) return FailedPrecondition("frames file " + path_ + " is already finished");
  std::uint8_t header[kFramesHeaderBytes];
  EncodeHeader(info_, header);
  std::FILE* f = file_.get();
  const bool ok = std::fseek(f, 0, SEEK_SET) == 0 &&
                  std::fwrite(header, 1, sizeof(header), f) == sizeof(header);
  const bool closed = std::fclose(file_.release()) == 0;
  if (!ok || !closed) return IoError("cannot finish frames file " + path_);
  return Status::Ok();
}

Result<FrameReader> FrameReader::Open(const std::string& path) {
  FrameReader r;
  r.file_.reset(std::fopen(path.c_str(), "rb"));
  if (!r.file_) return NotFound("cannot open frames file " + path);
  r.path_ = path;
  std::uint8_t h[kFramesHeaderBytes];
  if (std::fread(h, 1, sizeof(h), r.file_.get()) != sizeof(h)) {
    return Corrupt("frames file " + path + " is shorter than its " +
                   std::to_string(kFramesHeaderBytes) + "-byte header");
  }
  if (Get<std::uint32_t>(h, kOffMagic) != kFramesMagic) {
    return Corrupt("frames file " + path + " does not start with the ZMFR magic");
  }
  const auto version = Get<std::uint16_t>(h, kOffVersion);
  if (version != kFramesVersion && version != kFramesVersionNoImages) {
    return FailedPrecondition("frames file " + path + " has version " + std::to_string(version) +
                              ", this build reads versions " +
                              std::to_string(kFramesVersionNoImages) + " and " +
                              std::to_string(kFramesVersion));
  }
  if (Get<std::uint16_t>(h, kOffHeaderBytes) != kFramesHeaderBytes) {
    return Corrupt("frames file " + path + " has a header size other than " +
                   std::to_string(kFramesHeaderBytes));
  }
  FramesFileInfo& info = r.info_;
  info.frame_count = Get<std::uint64_t>(h, kOffCount);
  info.max_features = Get<std::uint32_t>(h, kOffMaxFeatures);
  info.camera.fx = Get<double>(h, kOffFx);
  info.camera.fy = Get<double>(h, kOffFy);
  info.camera.cx = Get<double>(h, kOffCx);
  info.camera.cy = Get<double>(h, kOffCy);
  info.camera.width = Get<std::uint32_t>(h, kOffWidth);
  info.camera.height = Get<std::uint32_t>(h, kOffHeight);
  info.rate_hz = Get<double>(h, kOffRate);
  info.max_colour_bytes = version >= 2 ? Get<std::uint32_t>(h, kOffMaxColour) : 0;
  info.image_width = version >= 2 ? Get<std::uint32_t>(h, kOffImageWidth) : 0;
  info.image_height = version >= 2 ? Get<std::uint32_t>(h, kOffImageHeight) : 0;
  if (info.max_colour_bytes > 0 &&
      (info.image_width == 0 || info.image_height == 0 || info.image_width > kMaxDenseSide ||
       info.image_height > kMaxDenseSide)) {
    return Corrupt("frames file " + path + " has images of " + std::to_string(info.image_width) +
                   "x" + std::to_string(info.image_height) + ", outside [1, " +
                   std::to_string(kMaxDenseSide) + "] per side");
  }
  if (info.max_colour_bytes > kMaxFrameColourBytes) {
    return Corrupt("frames file " + path + " claims colour images of " +
                   std::to_string(info.max_colour_bytes) + " bytes, limit " +
                   std::to_string(kMaxFrameColourBytes));
  }
  if (info.max_features > kMaxFeaturesPerKeyframe) {
    return Corrupt("frames file " + path + " claims " + std::to_string(info.max_features) +
                   " features per frame, limit " + std::to_string(kMaxFeaturesPerKeyframe));
  }
  if (!(info.camera.fx > 0.0 && info.camera.fy > 0.0 && std::isfinite(info.camera.cx) &&
        std::isfinite(info.camera.cy) && info.camera.width > 0 && info.camera.height > 0)) {
    return Corrupt("frames file " + path + " has invalid camera intrinsics");
  }
  return r;
}

Result<bool> FrameReader::Next(Frame* frame) {
  if (next_index_ >= info_.frame_count) return false;
  std::FILE* f = file_.get();
  std::uint8_t rec[kFrameRecordHeaderBytes];
  const auto where = [&] {
    return "frames file " + path_ + ": frame " + std::to_string(next_index_) + " at byte " +
           std::to_string(offset_);
  };
  if (std::fread(rec, 1, sizeof(rec), f) != sizeof(rec)) {
    return Corrupt(where() + " is truncated (header says " + std::to_string(info_.frame_count) +
                   " frames)");
  }
  const auto index = Get<std::uint64_t>(rec, 0);
  const auto stamp = Get<double>(rec, 8);
  const auto n = Get<std::uint32_t>(rec, 72);
  const auto colour_bytes = Get<std::uint32_t>(rec, kOffRecordColourBytes);
  if (colour_bytes > info_.max_colour_bytes) {
    return Corrupt(where() + " has a colour image of " + std::to_string(colour_bytes) +
                   " bytes, header limit " + std::to_string(info_.max_colour_bytes));
  }
  if (index != next_index_) {
    return Corrupt(where() + " has index " + std::to_string(index));
  }
  if (n > info_.max_features) {
    return Corrupt(where() + " has " + std::to_string(n) + " features, header limit " +
                   std::to_string(info_.max_features));
  }
  if (!std::isfinite(stamp) || (next_index_ > 0 && stamp < last_stamp_s_)) {
    return Corrupt(where() + " has a stamp out of order");
  }
  double pose[7];
  for (std::size_t i = 0; i < 7; ++i) pose[i] = Get<double>(rec, 16 + 8 * i);
  frame->index = index;
  frame->stamp_s = stamp;
  Eigen::Quaterniond q(pose[6], pose[3], pose[4], pose[5]);
  const double qn = q.norm();
  if (!(qn > 0.5 && qn < 2.0)) return Corrupt(where() + " has an invalid odometry quaternion");
  q.coeffs() /= qn;
  frame->odom = Pose3::Identity();
  frame->odom.linear() = q.toRotationMatrix();
  frame->odom.translation() = Eigen::Vector3d(pose[0], pose[1], pose[2]);
  frame->descriptors.resize(n);
  frame->keypoints.resize(2 * std::size_t{n});
  if (n > 0) {
    const bool ok =
        std::fread(frame->descriptors.data(), kDescriptorBytes, n, f) == n &&
        std::fread(frame->keypoints.data(), sizeof(float), 2 * std::size_t{n}, f) ==
            2 * std::size_t{n};
    if (!ok) return Corrupt(where() + " is truncated inside its features");
  }
  frame->colour.resize(colour_bytes);
  frame->colour_codec = colour_bytes > 0 ? ImageCodec::kJpeg : ImageCodec::kNone;
  frame->depth.clear();
  frame->depth_codec = ImageCodec::kNone;
  if (colour_bytes > 0 && std::fread(frame->colour.data(), 1, colour_bytes, f) != colour_bytes) {
    return Corrupt(where() + " is truncated inside its colour image");
  }
  offset_ += kFrameRecordHeaderBytes + std::size_t{n} * (kDescriptorBytes + 2 * sizeof(float)) +
             colour_bytes;
  last_stamp_s_ = stamp;
  ++next_index_;
  return true;
}

Status FrameReader::Rewind() {
  if (std::fseek(file_.get(), static_cast<long>(kFramesHeaderBytes), SEEK_SET) != 0) {
    return IoError("cannot rewind frames file " + path_);
  }
  next_index_ = 0;
  offset_ = kFramesHeaderBytes;
  last_stamp_s_ = 0.0;
  return Status::Ok();
}

}  // namespace zm
