// The score stage of room segmentation: a ground-truth image read as room labels, and a
// segmentation scored against it (precision, recall and IoU as ROSE² measures them).
#pragma once

#include <opencv2/core/mat.hpp>
#include <string>

#include "common/status.h"

namespace zm {

// Ground truth: every flat colour is one room (labels 1..N in order of first appearance,
// scanning rows), black (all channels <= 20) is no room, and so is a colour covering fewer than
// `min_room_cells` cells (the shared ground truths carry hundreds of stray anti-aliased colours
// of <= 136 cells beside rooms of >= 435 cells). Errors name the file.
inline constexpr int kDefaultMinGtRoomCells = 200;
[[nodiscard]] Result<cv::Mat> LoadGroundTruthLabels(const std::string& path,
                                                    int min_room_cells = kDefaultMinGtRoomCells);

struct SegmentationScore {
  double precision = 0.0;      // [0, 1], area-weighted best-GT fraction of each predicted segment
  double recall = 0.0;         // [0, 1], area-weighted best-segment fraction of each GT room
  double mean_iou = 0.0;       // [0, 1], mean over GT rooms of the best IoU with one segment
  double mean_iou_full = 0.0;  // the same over every cell of room and segment (stricter)
  // mean_iou over the GT rooms the map shows: those with at least `min_shown_cells` cells the
  // map holds as free (without a map, every GT room). A room the robot never entered is not a
  // room any segmentation of its grid can find; mean_iou counts it as 0 (issue 28).
  double mean_iou_shown = 0.0;
  int gt_rooms = 0;
  int gt_rooms_shown = 0;
  int predicted_segments = 0;
};

// Scores `predicted` against `ground_truth` (both CV_32SC1, 0 = none) over their common top-left
// size (a map and its ground truth can differ by a pixel). Precision and recall count only cells
// that are in some GT room and in some predicted segment (ROSE² evaluation); mean_iou counts the
// same cells, mean_iou_full all cells of both (free cells the GT leaves out, GT cells that are
// not free in the map). `free_cells` (CV_8UC1, non-zero = free in the map, or empty) decides
// which GT rooms the map shows, for mean_iou_shown; a room is shown from `min_shown_cells` free
// cells, the size under which a GT colour is not a room at all. Errors on a wrong type.
[[nodiscard]] Result<SegmentationScore> ScoreSegmentation(
    const cv::Mat& predicted, const cv::Mat& ground_truth, const cv::Mat& free_cells = cv::Mat(),
    int min_shown_cells = kDefaultMinGtRoomCells);

}  // namespace zm
