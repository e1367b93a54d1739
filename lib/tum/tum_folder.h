// TUM RGB-D folders (Sturm et al. 2012,
// https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats): what is in one (one frame's
// images are read by tum_frame.h). Used to build a map (`zonemap import-tum`,
// lib/import/tum_import.h) and to replay one into zonemapd (`zonemapd --tum`, tum_replay.h,
// which lists the folder here and leaves reading the images to zonemapd's front-end); so listing
// a folder and reading a frame's images are separate targets, and nothing here builds a map.
//
//   rgb.txt, depth.txt   "stamp path" a line, '#' comments; paths relative to the folder
//   associations.txt     "rgb_stamp rgb_path depth_stamp depth_path" (associate.py's output);
//                        used instead of the two lists when present; a file written with the
//                        depth pair first (its second column under depth/) is read as such
//   colour               8-bit PNG (3 or 4 channels; grey accepted), of the camera's size
//   depth                16-bit PNG, 5,000 per metre (TUM's factor), 0 = no depth
//   intrinsics           by option; the defaults are freiburg1's (fx 517.3, fy 516.5, cx 318.6,
//                        cy 255.3, 640 x 480); TUM's images are not undistorted
//
// A colour frame is associated with the depth frame of the nearest stamp within
// max_stamp_difference_s (0.02 s, associate.py's default); a depth frame may serve two colour
// frames. A colour frame with none is a gap: counted and reported, never an error. A malformed
// line is reported with its line number and skipped. Missing and unreadable images are found
// when a frame is read (ReadTumFrame, tum_frame.h): one Status line naming the file, never a
// crash.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"
#include "mapdb/map_db.h"

namespace zm {

// freiburg1's colour camera, TUM's published intrinsics.
inline constexpr CameraIntrinsics kTumFr1Camera{517.3, 516.5, 318.6, 255.3, 640, 480};
inline constexpr double kTumDepthUnitsPerMetre = 5000.0;

struct TumFolderOptions {
  double max_stamp_difference_s = 0.02;  // colour-depth association tolerance
  CameraIntrinsics camera = kTumFr1Camera;
  double depth_units_per_m = kTumDepthUnitsPerMetre;
};

// Checks the ranges (tolerance > 0 and finite, camera positive, units > 0).
[[nodiscard]] Status ValidateTumFolderOptions(const TumFolderOptions& options);

struct TumFrameFiles {
  double stamp_s = 0.0;        // the colour frame's stamp: the frame's
  std::string rgb_path;        // folder-joined
  double depth_stamp_s = 0.0;
  std::string depth_path;
};

struct TumFolder {
  std::string dir;
  std::string listing;  // "associations.txt" or "rgb.txt + depth.txt"
  std::vector<TumFrameFiles> frames;  // associated, by colour stamp
  std::uint32_t colour_entries = 0;   // lines naming a colour image
  std::uint32_t depth_entries = 0;    // lines naming a depth image
  std::uint32_t gaps = 0;             // colour frames without depth within the tolerance
  // Those colour frames (depth_path empty), by stamp: a replay (tum_replay.h) runs them on
  // odometry, counted, where they fall; an import leaves them out.
  std::vector<TumFrameFiles> gap_frames;
  std::uint32_t malformed_lines = 0;
  std::vector<std::string> problems;  // one line each: gaps and malformed lines
};

// Lists `dir`. Errors: no folder, neither associations.txt nor rgb.txt and depth.txt, an
// unreadable list, a list with no usable line.
[[nodiscard]] Result<TumFolder> ReadTumFolder(const std::string& dir,
                                              const TumFolderOptions& options = {});

}  // namespace zm
