// The frames file (frames.bin): the camera frames of a localization run, as the runtime's replay
// source reads them. Written by the simulator, read one frame at a time into a reserved Frame
// without allocating (Next() only resizes vectors within the capacity Reserve() gave them).
//
// Layout (little-endian, no padding between records):
//
//   offset 0   FramesFileHeader (128 bytes)
//                magic "ZMFR" (0x52464D5A), version (1), header_bytes (128),
//                frame_count, max_features (largest feature_count of any record),
//                camera intrinsics (fx, fy, cx, cy as float64; width, height as uint32),
//                rate_hz (float64), max_colour_bytes u32 (version 2; largest colour_bytes of
//                any record), image_width u32, image_height u32 (version 2: the colour images'
//                size, the camera's field of view at another resolution; 0 without images),
//                reserved zero bytes
//   128        frame_count records, each:
//                FrameRecordHeader (80 bytes): index u64, stamp_s f64,
//                  odom tx ty tz qx qy qz qw (7 x f64), feature_count u32,
//                  colour_bytes u32 (version 2; reserved zero in version 1)
//                descriptors  feature_count x 32 bytes
//                keypoints    feature_count x 2 float32 (u, v pixels)
//                colour       colour_bytes: the frame's colour image as JPEG (issue 26: the
//                             camera's frame, from which the loop extracts its features)
//
// Invariants: records are in increasing index order starting at 0 with non-decreasing stamps;
// every feature_count <= max_features <= kMaxFeaturesPerKeyframe and every colour_bytes <=
// max_colour_bytes <= kMaxFrameColourBytes; the file length equals 128 + sum(80 + 40 *
// feature_count + colour_bytes). The reader checks all of this and reports a truncated or
// inconsistent file as kCorrupt naming the file, the frame and the byte offset. Version 1 files
// (no images) are read as before.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "common/status.h"
#include "localization/frame.h"
#include "mapdb/map_db.h"

namespace zm {

inline constexpr std::uint32_t kFramesMagic = 0x52464D5A;  // "ZMFR"
inline constexpr std::uint16_t kFramesVersion = 2;        // written
inline constexpr std::uint16_t kFramesVersionNoImages = 1;  // still read
// A frame's encoded colour image larger than this is corrupt (a 4096 x 4096 JPEG at quality 100
// is about 10 MB).
inline constexpr std::uint32_t kMaxFrameColourBytes = 32u << 20;
inline constexpr std::size_t kFramesHeaderBytes = 128;
inline constexpr std::size_t kFrameRecordHeaderBytes = 80;

// What the header of a frames file says.
struct FramesFileInfo {
  std::uint64_t frame_count = 0;
  std::uint32_t max_features = 0;
  std::uint32_t max_colour_bytes = 0;  // 0: no frame carries an image
  std::uint32_t image_width = 0;       // the images' size (same field of view as `camera`)
  std::uint32_t image_height = 0;
  CameraIntrinsics camera;
  double rate_hz = 0.0;
};

// Writes a frames file. Frames are appended in order; Finish() writes the final count and
// max_features into the header and closes the file. A writer destroyed without Finish() leaves a
// file whose header says 0 frames (the reader then sees an empty or inconsistent file).
class FrameWriter {
 public:
  [[nodiscard]] static Result<FrameWriter> Create(const std::string& path,
                                                  const CameraIntrinsics& camera, double rate_hz);
  FrameWriter(FrameWriter&&) noexcept = default;
  FrameWriter& operator=(FrameWriter&&) noexcept = default;
  ~FrameWriter() = default;

  // Appends one frame; its index must be the number of frames written so far and its stamp not
  // earlier than the previous one; keypoints.size() must be 2 * descriptors.size(). A frame's
  // colour image is written when it has one, and must be JPEG.
  Status Append(const Frame& frame);
  // The size of the frames' colour images (default: the camera's), recorded in the header.
  void SetImageSize(std::uint32_t width, std::uint32_t height) {
    info_.image_width = width;
    info_.image_height = height;
  }
  Status Finish();
  [[nodiscard]] std::uint64_t count() const { return info_.frame_count; }

 private:
  struct FileCloser {
    void operator()(std::FILE* f) const {
      if (f != nullptr) std::fclose(f);
    }
  };
  FrameWriter() = default;
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::string path_;
  FramesFileInfo info_;
  double last_stamp_s_ = 0.0;
};

// Reads a frames file front to back. Move-only; the file handle is closed by RAII.
class FrameReader {
 public:
  // Opens and validates the header (magic, version, header size, camera, max_features) and the
  // file length against nothing yet: a truncated record is reported by Next().
  [[nodiscard]] static Result<FrameReader> Open(const std::string& path);
  FrameReader(FrameReader&&) noexcept = default;
  FrameReader& operator=(FrameReader&&) noexcept = default;
  ~FrameReader() = default;

  // Reads the next frame into *frame. Returns false at the end (after count() frames). Does not
  // allocate when frame->Reserve(max_features(), max_colour_bytes()) was called. On error
  // *frame is unspecified.
  [[nodiscard]] Result<bool> Next(Frame* frame);
  // Goes back to the first frame (a replay that loops).
  Status Rewind();

  [[nodiscard]] std::uint64_t count() const { return info_.frame_count; }
  [[nodiscard]] std::uint32_t max_features() const { return info_.max_features; }
  [[nodiscard]] std::uint32_t max_colour_bytes() const { return info_.max_colour_bytes; }
  [[nodiscard]] const CameraIntrinsics& camera() const { return info_.camera; }
  [[nodiscard]] double rate_hz() const { return info_.rate_hz; }
  [[nodiscard]] const FramesFileInfo& info() const { return info_; }

 private:
  struct FileCloser {
    void operator()(std::FILE* f) const {
      if (f != nullptr) std::fclose(f);
    }
  };
  FrameReader() = default;
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::string path_;
  FramesFileInfo info_;
  std::uint64_t next_index_ = 0;
  std::uint64_t offset_ = kFramesHeaderBytes;
  double last_stamp_s_ = 0.0;
};

}  // namespace zm
