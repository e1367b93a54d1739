// One TUM RGB-D frame's images, decoded (ReadTumFrame): for `zonemap import-tum`
// (lib/import/tum_import.cc). A target of its own (zm_tum_frame), apart from the folder listing
// (tum_folder.h, zm_tum), because it decodes with OpenCV's imgcodecs, which zonemapd must not
// link: zonemapd --tum lists a folder here and its front-end decodes the images itself
// (lib/mapdb/png_decoder.h says why).
#pragma once

#include <opencv2/core/mat.hpp>

#include "common/status.h"
#include "tum/tum_folder.h"

namespace zm {

struct TumFrameImages {
  cv::Mat colour;   // 8UC3 BGR (8UC1 grey kept as is)
  cv::Mat depth16;  // 16UC1, options.depth_units_per_m per metre
};

// Reads and checks one frame's images (into `out`, reusing its buffers where OpenCV can): a
// missing, unreadable or truncated file, a colour image that is not 8-bit, a depth image that is
// not 16-bit single-channel, or either not of the camera's size is one error naming the file
// and the limit; `out` is then left empty.
[[nodiscard]] Status ReadTumFrame(const TumFrameFiles& frame, const TumFolderOptions& options,
                                  TumFrameImages* out);

}  // namespace zm
