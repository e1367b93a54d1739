// Camera frames as image files, at zonemapd's input edge (issue 26 §4): an `image` line names a
// colour and a depth file a camera driver wrote (line_protocol.h), and a recorded folder (a TUM
// RGB-D sequence: lib/tum/tum_replay.h) yields the same per frame (CameraFileSource). The session
// (daemon.h) reads the colour file here, into the Frame's encoded colour buffer, and the tick
// loop's front-end decodes and extracts it exactly as it does a recorded frame's JPEG.
//
// What is read and checked, and by whom:
//   colour   read here whole into Frame::colour (reserved once: MaxEncodedImageBytes of the
//            images' size), its codec from the first bytes (PNG or JPEG). Missing, unreadable,
//            empty, neither PNG nor JPEG: kUnreadable; larger than the reserve: kTooLarge.
//            Truncated, undecodable and wrong-size images are the front-end's to find when it
//            decodes them inside the tick (front_end.h): kFrontEnd.
//   depth    NOT read: nothing in the loop uses a frame's depth. The localizer matches the
//            frame's 2-D keypoints against the resident keyframes' 3-D points (PnP), and the
//            front-end extracts from the colour image only. Its file is only looked at (one
//            stat): an image frame is an RGB-D pair, so a depth file that is missing or empty
//            (or a folder that lists none for the frame: a TUM gap) refuses the frame
//            (kNoDepth) -- the driver that lost its depth stream is told, not silently run on
//            colour. `-` says the camera has no depth, and is accepted.
// A refused image frame still carries its odometry: the session ticks it without an image, so
// the loop goes on on odometry and the robot gets its pose line; the refusal is counted by
// reason (ImageRefusalCounts) with one stderr line naming the file and the limit.
//
// Nothing here allocates: open/fstat/read into the reserved buffer, messages into a TextLine.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common/status.h"
#include "geometry/pose.h"
#include "localization/frame.h"
#include "mapdb/map_db.h"
#include "runtime/line_protocol.h"
#include "runtime/text_line.h"

namespace zm {

// Why an image frame ran on odometry.
enum class ImageRefusal : std::uint8_t {
  kUnreadable = 0,  // colour file missing, unreadable, empty, or neither PNG nor JPEG
  kTooLarge,        // colour file larger than the reserve (MaxEncodedImageBytes)
  kNoDepth,         // depth file missing or empty, or none listed for the frame (TUM gap)
  kFrontEnd,        // the front-end refused the colour image: truncated, corrupt, wrong size
  kCount
};
inline constexpr std::size_t kImageRefusalCount = static_cast<std::size_t>(ImageRefusal::kCount);
// Stable snake_case names (summary.json, stderr): "no_depth".
[[nodiscard]] const char* ImageRefusalName(ImageRefusal reason);

struct ImageRefusalCounts {
  std::array<std::uint64_t, kImageRefusalCount> by_reason{};
  std::uint64_t total = 0;
  void Add(ImageRefusal r) {
    ++by_reason[static_cast<std::size_t>(r)];
    ++total;
  }
  [[nodiscard]] std::uint64_t operator[](ImageRefusal r) const {
    return by_reason[static_cast<std::size_t>(r)];
  }
};

// The bytes reserved for one encoded colour image of width x height: an 8-bit BGRA PNG stored
// without compression (4 bytes a pixel, a filter byte a row, zlib's and the chunks' framing in
// 64 KiB); any JPEG or compressed PNG of that size is smaller. 1.3 MB at 640 x 480.
[[nodiscard]] std::uint32_t MaxEncodedImageBytes(std::uint32_t width, std::uint32_t height);

// Images of width x height show the map camera's field of view at another resolution (a plain
// scale, ScaledIntrinsics): the aspect ratio within a pixel. An error names both sizes.
[[nodiscard]] Status CheckImageSize(const CameraIntrinsics& map_camera, std::uint32_t width,
                                    std::uint32_t height);

// Reads colour files into reserved frames and looks at depth files (see the file comment).
class ImageFileReader {
 public:
  // Images of width x height; a colour file is read only when it fits in `max_colour_bytes`
  // (the frames' reserve).
  void Configure(std::uint32_t width, std::uint32_t height, std::uint32_t max_colour_bytes) {
    width_ = width;
    height_ = height;
    max_colour_bytes_ = max_colour_bytes;
  }

  // true: frame->colour holds the file and colour_codec its codec. false: *why and the reason in
  // words, naming the file (appended to *message); frame->colour is then empty, the codec kNone.
  // frame->colour must have capacity for max_colour_bytes (Frame::Reserve): no allocation.
  bool ReadColour(std::string_view path, Frame* frame, ImageRefusal* why, TextLine* message);
  // true for "-" and for an existing non-empty file. false: kNoDepth with the reason (`note` says
  // why a folder has no depth for the frame when path is empty).
  bool CheckDepth(std::string_view path, std::string_view note, ImageRefusal* why,
                  TextLine* message);

 private:
  // `path` NUL-terminated in path_; false when it does not fit (never: the parser and the
  // folder reader bound paths to kMaxImagePathBytes).
  bool Terminate(std::string_view path);

  std::uint32_t width_ = 0;
  std::uint32_t height_ = 0;
  std::uint32_t max_colour_bytes_ = 0;
  char path_[kMaxImagePathBytes + 1] = {};
};

// One camera frame as files: what an `image` line carries, and what a recorded folder yields.
struct CameraFrameFiles {
  double stamp_s = 0.0;
  Pose3 odom = Pose3::Identity();  // odometry (body, odom frame), as a frame line's
  std::string_view colour_path;
  std::string_view depth_path;  // "-": no depth camera; empty: the folder has none (a gap)
  std::string_view note;        // why depth_path is empty, for the diagnostic
};

// A recorded sequence of camera frames as files (zonemapd --tum: lib/tum/tum_replay.h), replayed
// by the session as fast as it ticks, like a frames file (--frames). The views it hands out stay
// valid until the next call.
class CameraFileSource {
 public:
  virtual ~CameraFileSource() = default;
  // true: *out holds the next frame; false: the end. Never allocates.
  [[nodiscard]] virtual Result<bool> Next(CameraFrameFiles* out) = 0;
  // The images' size (fixed for the sequence).
  [[nodiscard]] virtual std::uint32_t width() const = 0;
  [[nodiscard]] virtual std::uint32_t height() const = 0;
  // The hello line's input name ("tum").
  [[nodiscard]] virtual const char* kind() const = 0;
  // Frames whose odometry was held from the frame before (no pose in the odometry file within
  // its tolerance, or no odometry file at all).
  [[nodiscard]] virtual std::uint64_t frames_without_odometry() const { return 0; }
};

}  // namespace zm
