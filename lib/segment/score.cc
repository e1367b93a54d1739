// The score stage (score.h): ground-truth images and the ROSE² measures.
#include "segment/score.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unordered_map>
#include <vector>

#include "segment/grid_map.h"

namespace zm {
namespace {

using segment_detail::Idx;

}  // namespace

Result<cv::Mat> LoadGroundTruthLabels(const std::string& path, int min_room_cells) {
  ZM_ASSIGN_OR_RETURN(const cv::Mat img, ReadImageFile(path, cv::IMREAD_COLOR));
  cv::Mat labels = cv::Mat::zeros(img.size(), CV_32S);
  std::unordered_map<std::uint32_t, int> ids;
  for (int r = 0; r < img.rows; ++r) {
    const cv::Vec3b* p = img.ptr<cv::Vec3b>(r);
    int* l = labels.ptr<int>(r);
    for (int c = 0; c < img.cols; ++c) {
      if (p[c][0] <= 20 && p[c][1] <= 20 && p[c][2] <= 20) continue;
      const std::uint32_t key =
          (std::uint32_t{p[c][0]} << 16) | (std::uint32_t{p[c][1]} << 8) | std::uint32_t{p[c][2]};
      auto [it, inserted] = ids.emplace(key, static_cast<int>(ids.size()) + 1);
      l[c] = it->second;
    }
  }
  // Colours covering fewer than min_room_cells are stray edge pixels of the hand drawing.
  std::vector<int> count(ids.size() + 1, 0);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) ++count[Idx(l[c])];
  }
  std::vector<int> renumber(ids.size() + 1, 0);
  int next = 0;
  for (std::size_t i = 1; i < count.size(); ++i) {
    if (count[i] >= min_room_cells) renumber[i] = ++next;
  }
  for (int r = 0; r < labels.rows; ++r) {
    int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) l[c] = renumber[Idx(l[c])];
  }
  return labels;
}

Result<SegmentationScore> ScoreSegmentation(const cv::Mat& predicted, const cv::Mat& ground_truth,
                                            const cv::Mat& free_cells, int min_shown_cells) {
  if (predicted.type() != CV_32SC1 || ground_truth.type() != CV_32SC1) {
    return InvalidArgument("scoring needs two CV_32SC1 label images");
  }
  if (!free_cells.empty() && free_cells.type() != CV_8UC1) {
    return InvalidArgument("scoring's free-cell mask must be CV_8UC1");
  }
  const int rows = std::min(predicted.rows, ground_truth.rows);
  const int cols = std::min(predicted.cols, ground_truth.cols);
  std::map<int, std::int64_t> gt_free;                  // GT room -> cells the map holds as free
  std::map<std::pair<int, int>, std::int64_t> overlap;  // (pred, gt) -> cells
  std::map<int, std::int64_t> pred_area, gt_area;       // restricted to cells in both
  std::map<int, std::int64_t> gt_full, pred_full;       // every cell
  std::map<int, bool> gt_present, pred_present;
  std::int64_t total = 0;
  for (int r = 0; r < rows; ++r) {
    const int* p = predicted.ptr<int>(r);
    const int* g = ground_truth.ptr<int>(r);
    for (int c = 0; c < cols; ++c) {
      if (g[c] > 0) {
        gt_present[g[c]] = true, ++gt_full[g[c]];
        const bool is_free = free_cells.empty() || (r < free_cells.rows && c < free_cells.cols &&
                                                    free_cells.at<std::uint8_t>(r, c) != 0);
        if (is_free) ++gt_free[g[c]];
      }
      if (p[c] > 0) pred_present[p[c]] = true, ++pred_full[p[c]];
      if (p[c] <= 0 || g[c] <= 0) continue;
      ++overlap[{p[c], g[c]}];
      ++pred_area[p[c]];
      ++gt_area[g[c]];
      ++total;
    }
  }
  SegmentationScore score;
  score.gt_rooms = static_cast<int>(gt_present.size());
  score.predicted_segments = static_cast<int>(pred_present.size());
  if (total == 0) return score;
  std::map<int, std::int64_t> best_for_pred, best_for_gt;
  std::map<int, double> best_iou, best_iou_full;
  for (const auto& [key, n] : overlap) {
    const auto [p, g] = key;
    best_for_pred[p] = std::max(best_for_pred[p], n);
    best_for_gt[g] = std::max(best_for_gt[g], n);
    const double iou = static_cast<double>(n) / static_cast<double>(pred_area[p] + gt_area[g] - n);
    best_iou[g] = std::max(best_iou[g], iou);
    const double full = static_cast<double>(n) / static_cast<double>(pred_full[p] + gt_full[g] - n);
    best_iou_full[g] = std::max(best_iou_full[g], full);
  }
  std::int64_t sum_p = 0, sum_g = 0;
  for (const auto& [p, n] : best_for_pred) sum_p += n;
  for (const auto& [g, n] : best_for_gt) sum_g += n;
  score.precision = static_cast<double>(sum_p) / static_cast<double>(total);
  score.recall = static_cast<double>(sum_g) / static_cast<double>(total);
  double iou_sum = 0.0;
  for (const auto& [g, iou] : best_iou) iou_sum += iou;
  score.mean_iou = score.gt_rooms > 0 ? iou_sum / score.gt_rooms : 0.0;
  double shown_sum = 0.0;
  for (const auto& [g, n] : gt_free) {
    if (free_cells.empty() || n >= min_shown_cells) {
      ++score.gt_rooms_shown;
      if (auto it = best_iou.find(g); it != best_iou.end()) shown_sum += it->second;
    }
  }
  score.mean_iou_shown = score.gt_rooms_shown > 0 ? shown_sum / score.gt_rooms_shown : 0.0;
  double full_sum = 0.0;
  for (const auto& [g, iou] : best_iou_full) full_sum += iou;
  score.mean_iou_full = score.gt_rooms > 0 ? full_sum / score.gt_rooms : 0.0;
  return score;
}

}  // namespace zm
