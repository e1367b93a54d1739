// One TUM frame's images (see tum_frame.h).
#include "tum/tum_frame.h"

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>

namespace zm {

namespace fs = std::filesystem;

namespace {

// Reads and decodes one image file; errors name it.
Status ReadImage(const std::string& path, int flags, const char* what, cv::Mat* out) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    return NotFound(std::string(what) + " " + path + " is missing");
  std::ifstream in(path, std::ios::binary);
  if (!in) return IoError("cannot open " + std::string(what) + " " + path);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  const std::string data = bytes.str();
  if (data.empty()) return Corrupt(std::string(what) + " " + path + " is empty (0 bytes)");
  try {
    const cv::Mat raw(1, static_cast<int>(data.size()), CV_8UC1, const_cast<char*>(data.data()));
    *out = cv::imdecode(raw, flags);
  } catch (const cv::Exception& e) {
    return Corrupt(std::string(what) + " " + path + " cannot be decoded: " + e.what());
  }
  if (out->empty()) {
    return Corrupt(std::string(what) + " " + path + " (" + std::to_string(data.size()) +
                   " bytes) cannot be decoded: truncated or not an image");
  }
  return Status::Ok();
}

std::string Size(const cv::Mat& m) { return std::to_string(m.cols) + "x" + std::to_string(m.rows); }

}  // namespace

Status ReadTumFrame(const TumFrameFiles& frame, const TumFolderOptions& options,
                    TumFrameImages* out) {
  const auto fail = [&](Status s) {
    out->colour.release();
    out->depth16.release();
    return s;
  };
  const int w = static_cast<int>(options.camera.width), h = static_cast<int>(options.camera.height);
  const std::string expect = std::to_string(w) + "x" + std::to_string(h);
  Status st = ReadImage(frame.rgb_path, cv::IMREAD_UNCHANGED, "colour image", &out->colour);
  if (!st.ok()) return fail(st);
  if (out->colour.depth() != CV_8U ||
      (out->colour.channels() != 1 && out->colour.channels() != 3 && out->colour.channels() != 4)) {
    return fail(InvalidArgument("colour image " + frame.rgb_path + " has OpenCV type " +
                                std::to_string(out->colour.type()) +
                                ": expected 8-bit grey, BGR or BGRA"));
  }
  if (out->colour.channels() == 4) cv::cvtColor(out->colour, out->colour, cv::COLOR_BGRA2BGR);
  if (out->colour.cols != w || out->colour.rows != h) {
    return fail(InvalidArgument("colour image " + frame.rgb_path + " is " + Size(out->colour) +
                                ", the camera is " + expect));
  }
  st = ReadImage(frame.depth_path, cv::IMREAD_ANYDEPTH, "depth image", &out->depth16);
  if (!st.ok()) return fail(st);
  if (out->depth16.type() != CV_16UC1) {
    return fail(InvalidArgument("depth image " + frame.depth_path + " has OpenCV type " +
                                std::to_string(out->depth16.type()) +
                                ": expected 16-bit single-channel (16UC1)"));
  }
  if (out->depth16.cols != w || out->depth16.rows != h) {
    return fail(InvalidArgument("depth image " + frame.depth_path + " is " + Size(out->depth16) +
                                ", the camera is " + expect));
  }
  return Status::Ok();
}

}  // namespace zm
