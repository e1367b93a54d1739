// Writes small TUM RGB-D folders for tests (issue 26): colour PNGs cut from one procedural
// texture (rectangles, discs and noise, so ORB finds features; consecutive frames overlap),
// 16-bit depth PNGs at 5,000 per metre (a slanted plane), rgb.txt / depth.txt or
// associations.txt, and a groundtruth trajectory of the colour camera. Options damage it: gaps,
// a missing, an unreadable, a truncated or a wrong-size image. No real TUM recording can be
// downloaded here, so every TUM test writes its own folder.
#pragma once

#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>
#include <vector>

#include "mapdb/map_db.h"

namespace zm::test {

struct TumFolderSpec {
  int frames = 12;
  int width = 320;
  int height = 240;
  double step_m = 0.1;              // camera motion per frame along the map's x
  double frame_dt_s = 1.0 / 30.0;
  bool associations = false;        // associations.txt instead of rgb.txt + depth.txt
  std::set<int> depth_gaps;         // frames whose depth line and file are left out
  std::set<int> missing_colour;     // listed, file not written
  std::set<int> unreadable_colour;  // listed, file holds no image
  std::set<int> truncated_depth;    // listed, PNG cut in half
  std::set<int> wrong_size_colour;  // listed, half the size
  unsigned seed = 1;
};

inline CameraIntrinsics TumTestCamera(const TumFolderSpec& s) {
  return CameraIntrinsics{0.8 * s.width, 0.8 * s.width, 0.5 * s.width, 0.5 * s.height,
                          static_cast<std::uint32_t>(s.width), static_cast<std::uint32_t>(s.height)};
}

inline std::string TumStamp(double s) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", s);
  return buf;
}

// The procedural texture every frame is cut from: wide enough for every frame's window.
inline cv::Mat TumTexture(const TumFolderSpec& s) {
  cv::RNG rng(s.seed);
  const int w = s.width + s.frames * 12 + 16, h = s.height;
  cv::Mat tex(h, w, CV_8UC3);
  rng.fill(tex, cv::RNG::UNIFORM, cv::Scalar::all(60), cv::Scalar::all(190));
  cv::GaussianBlur(tex, tex, cv::Size(0, 0), 3.0);
  for (int i = 0; i < w * h / 900; ++i) {
    const cv::Point a(rng.uniform(0, w), rng.uniform(0, h));
    const cv::Scalar c(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(0, 256));
    if (i % 2 == 0) {
      cv::rectangle(tex, a, a + cv::Point(rng.uniform(4, 30), rng.uniform(4, 30)), c, cv::FILLED);
    } else {
      cv::circle(tex, a, rng.uniform(3, 15), c, cv::FILLED);
    }
  }
  return tex;
}

// Writes the folder and a groundtruth.txt (returned path) into `dir`.
inline std::string WriteTumFolder(const std::filesystem::path& dir, const TumFolderSpec& s) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "rgb");
  fs::create_directories(dir / "depth");
  const cv::Mat tex = TumTexture(s);
  std::ofstream rgb_list, depth_list, assoc;
  if (s.associations) {
    assoc.open(dir / "associations.txt");
  } else {
    rgb_list.open(dir / "rgb.txt");
    depth_list.open(dir / "depth.txt");
    rgb_list << "# color images\n# timestamp filename\n";
    depth_list << "# depth maps\n# timestamp filename\n";
  }
  std::ofstream gt(dir / "groundtruth.txt");
  gt << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  for (int i = 0; i < s.frames; ++i) {
    const double t = 1305031100.0 + i * s.frame_dt_s;
    const double td = t + 0.004;  // depth a few ms after colour, as the Kinect's
    const std::string rgb_name = "rgb/" + TumStamp(t) + ".png";
    const std::string depth_name = "depth/" + TumStamp(td) + ".png";
    cv::Mat colour = tex(cv::Rect(i * 12, 0, s.width, s.height)).clone();
    cv::Mat depth(s.height, s.width, CV_16UC1);
    for (int v = 0; v < s.height; ++v) {
      for (int u = 0; u < s.width; ++u) {
        depth.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>((2.0 + 0.002 * u) * 5000.0);
      }
    }
    if (s.wrong_size_colour.contains(i)) cv::resize(colour, colour, cv::Size(s.width / 2, s.height / 2));
    if (s.unreadable_colour.contains(i)) {
      std::ofstream(dir / rgb_name) << "this is not a PNG";
    } else if (!s.missing_colour.contains(i)) {
      REQUIRE(cv::imwrite((dir / rgb_name).string(), colour));
    }
    const bool gap = s.depth_gaps.contains(i);
    if (!gap) {
      REQUIRE(cv::imwrite((dir / depth_name).string(), depth));
      if (s.truncated_depth.contains(i)) {
        const auto full = fs::file_size(dir / depth_name);
        fs::resize_file(dir / depth_name, full / 2);
      }
    }
    if (s.associations) {
      if (!gap) assoc << TumStamp(t) << ' ' << rgb_name << ' ' << TumStamp(td) << ' ' << depth_name << '\n';
    } else {
      rgb_list << TumStamp(t) << ' ' << rgb_name << '\n';
      if (!gap) depth_list << TumStamp(td) << ' ' << depth_name << '\n';
    }
    // The colour camera's pose: optical axes aligned with the map's, moving along x.
    gt << TumStamp(t + 0.001) << ' ' << s.step_m * i << " 0 1.2 0 0 0 1\n";
  }
  return (dir / "groundtruth.txt").string();
}

}  // namespace zm::test
