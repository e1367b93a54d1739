// Room segmentation: the stages (cut.h, merge.h, layout_merge.h) in order. OpenCV exceptions
// become Status values here.
#include "segment/segmentation.h"

#include <chrono>
#include <opencv2/core.hpp>
#include <string>

namespace zm {

Status CheckSegmentOptions(const SegmentOptions& o) {
  ZM_RETURN_IF_ERROR(CheckCutOptions(o.cut));
  ZM_RETURN_IF_ERROR(CheckRuleMergeOptions(o.rules));
  ZM_RETURN_IF_ERROR(CheckLearnedMergeOptions(o.learned));
  return CheckOutlineOptions(o.outline);
}

Result<Segmentation> SegmentRooms(const OccupancyGrid& grid, const SegmentOptions& options) {
  return SegmentRooms(grid, options, DefaultLayoutMergeModel());
}

Result<Segmentation> SegmentRooms(const OccupancyGrid& grid, const SegmentOptions& options,
                                  const LayoutMergeModel& model, const LayoutMergeTrace& trace) {
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed_ms = [&t0] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  if (grid.cells.empty() || grid.cells.type() != CV_8UC1) {
    return InvalidArgument("occupancy grid is empty or not 8-bit single-channel");
  }
  if (!(grid.resolution_m > 0.0)) {
    return InvalidArgument("occupancy grid resolution must be > 0, got " +
                           std::to_string(grid.resolution_m));
  }
  ZM_RETURN_IF_ERROR(CheckSegmentOptions(options));
  const bool layout = options.learned.layout_merge_threshold > 0.0;
  if (layout) ZM_RETURN_IF_ERROR(CheckLayoutMergeModelOptions(model, options.cut, options.rules));
  const double res = grid.resolution_m;
  Segmentation seg;
  try {
    Pieces pieces = CutPieces(grid, layout ? LayoutPieceCut(options.cut) : options.cut);
    seg.free_cleaned = pieces.free_cleaned;
    seg.wall_angle_rad = pieces.walls.angle_rad;
    seg.labels = cv::Mat::zeros(grid.cells.size(), CV_32S);
    if (pieces.box.area() <= 0) {
      seg.runtime_ms = elapsed_ms();
      return seg;
    }
    const cv::Rect box = pieces.box;
    cv::Mat& labels = pieces.labels;
    int count = 0;
    if (layout) {
      LayoutMergeInputs in;
      in.labels = &labels;
      in.count = MergeSmallSegments(&labels, pieces.count, 0);  // numbers pieces densely
      in.occupied = (grid.cells(box) == kCellOccupied) & (labels == 0);
      in.resolution_m = res;
      in.wall_angle_rad = pieces.walls.angle_rad;
      in.offset = box.tl();
      // The rule merges' segmentation of the same grid is the model's second opinion: they
      // were chosen on office buildings, where their corridors and halls are right.
      SegmentOptions rule_options = options;
      rule_options.learned.layout_merge_threshold = 0.0;
      ZM_ASSIGN_OR_RETURN(const Segmentation rules, SegmentRooms(grid, rule_options));
      in.rule_labels = rules.labels(box).clone();
      in.doorways = pieces.walls.doorways(box);  // views: `pieces` outlives the merge
      in.opening_kinds = pieces.walls.opening_kinds(box);
      ZM_ASSIGN_OR_RETURN(
          const int merged,
          MergeLayoutPieces(in, model, options.learned.layout_merge_threshold, trace));
      // Specks and slivers the model left alone (a laser map's stray free cells) are no zone
      // of their own, as in the rule merges.
      count = MergeSmallSegments(
          &labels, merged, static_cast<int>(options.learned.layout_min_area_m2 / (res * res)));
    } else {
      count = MergeByRules(options.rules, options.cut.door_max_width_m, res, &pieces);
    }
    seg.segments = DescribeSegments(labels, pieces.dt, count, res, options.kinds);
    labels.copyTo(seg.labels(box));
  } catch (const cv::Exception& e) {
    return Internal(std::string("room segmentation: OpenCV failed: ") + e.what());
  }
  seg.runtime_ms = elapsed_ms();
  return seg;
}

}  // namespace zm
