// What room segmentation produces (segmentation.h), shared by its stages.
//
// Invariants of a Segmentation: labels is CV_32SC1 of the grid's size; 0 = no zone, 1..N =
// segments[label - 1]; every labelled cell is free in the cleaned grid; each segment is one
// 4-connected region.
#pragma once

#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace zm {

struct SegmentInfo {
  int label = 0;     // value in Segmentation::labels
  std::string kind;  // "room" or "corridor"
  int area_cells = 0;
  double area_m2 = 0.0;
  double width_m = 0.0;     // twice the largest distance to an obstacle inside
  double elongation = 0.0;  // area / width^2 (length over width for a rectangle)
};

struct Segmentation {
  cv::Mat labels;  // CV_32SC1, 0 = none
  std::vector<SegmentInfo> segments;
  cv::Mat free_cleaned;         // CV_8UC1, 255 where the cleaned grid is free
  double wall_angle_rad = 0.0;  // dominant wall direction found by decluttering
  double rough_face_share = 0.0;  // the grid's, as read (cut.h, GridRoughFaceShare)
  bool rough_cut = false;  // the layout pieces were cut with the rough-grid options (cut.h)
  double runtime_ms = 0.0;
};

}  // namespace zm
