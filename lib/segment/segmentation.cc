// Room segmentation: the stages (cut.h, merge.h, layout_merge.h) in order. OpenCV exceptions
// become Status values here.
#include "segment/segmentation.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace zm {
namespace {

// The compiled-in model's gate (scripts/gate_layout_merge.py --gate 0.3): grids whose wall faces
// are rougher than this are merged by its robot half, and only they get MergeChannels.
constexpr double kChannelRoughFaceShare = 0.3;

}  // namespace

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
  // A grid without free space has no zone: an error, not an empty zone file. Only the known
  // part of the grid (free or occupied cells, with a rim of unknown ones so
  // the outside stays connected to the border) is segmented: a SLAM grid of 20000 x 20000 cells
  // around a 15 x 10 m flat took 9 minutes and 21 GB whole, and is a flat cropped.
  cv::Rect known;
  int free_cells = 0;
  try {
    free_cells = cv::countNonZero(grid.cells == kCellFree);
    known = cv::boundingRect(grid.cells != kCellUnknown);
  } catch (const cv::Exception& e) {
    return Internal(std::string("room segmentation: OpenCV failed: ") + e.what());
  }
  if (free_cells == 0) {
    return FailedPrecondition("occupancy grid has no free cell (" +
                              std::to_string(grid.cells.cols) + " x " +
                              std::to_string(grid.cells.rows) +
                              " cells, all occupied or unknown): no room to make a zone of");
  }
  const int rim = static_cast<int>(std::ceil(kKnownRimM / grid.resolution_m));
  known = cv::Rect(known.x - rim, known.y - rim, known.width + 2 * rim, known.height + 2 * rim) &
          cv::Rect(0, 0, grid.cells.cols, grid.cells.rows);
  if (static_cast<std::int64_t>(known.width) * known.height > kMaxSegmentCells) {
    return InvalidArgument(
        "occupancy grid: its known part (free or occupied cells) spans " +
        std::to_string(known.width) + " x " + std::to_string(known.height) +
        " cells, more than the " + std::to_string(kMaxSegmentCells) +
        " cells room segmentation takes (kMaxSegmentCells; at " +
        std::to_string(grid.resolution_m) +
        " m per cell); segment the building floor by floor or at a coarser resolution");
  }
  if (known.size() != grid.cells.size()) {
    OccupancyGrid part;
    part.cells = grid.cells(known).clone();
    part.resolution_m = grid.resolution_m;
    // origin_m is the bottom-left corner: the part's is known.x columns right and the rows
    // below the part up.
    part.origin_m =
        grid.origin_m +
        Eigen::Vector2d(known.x, grid.cells.rows - known.y - known.height) * grid.resolution_m;
    // The trace's ground truth is the whole grid's: the part's cell (0, 0) is its cell at
    // known.tl(). Without this view every pair of a cropped map was labelled from cells
    // known.tl() away (c375483 until the eighth round: map15's and map17's training rows).
    LayoutMergeTrace part_trace = trace;
    cv::Mat gt_part;
    if (trace.ground_truth != nullptr) {
      // known.tl() >= (0, 0), so the overlap starts there unless it is empty.
      const cv::Rect in_gt =
          known & cv::Rect(0, 0, trace.ground_truth->cols, trace.ground_truth->rows);
      gt_part = in_gt.area() > 0 ? (*trace.ground_truth)(in_gt)
                                 : cv::Mat(0, 0, trace.ground_truth->type());
      part_trace.ground_truth = &gt_part;
    }
    ZM_ASSIGN_OR_RETURN(Segmentation inner, SegmentRooms(part, options, model, part_trace));
    Segmentation whole = std::move(inner);
    cv::Mat labels = cv::Mat::zeros(grid.cells.size(), CV_32S);
    cv::Mat free_cleaned = cv::Mat::zeros(grid.cells.size(), CV_8U);
    whole.labels.copyTo(labels(known));
    whole.free_cleaned.copyTo(free_cleaned(known));
    whole.labels = labels;
    whole.free_cleaned = free_cleaned;
    whole.runtime_ms = elapsed_ms();
    return whole;
  }
  const bool layout = options.learned.layout_merge_threshold > 0.0;
  // An oracle trace merges by the ground truth, not the model: it is how a model for other cut
  // options is trained (scripts/train_layout_merge.py --param), so the model's options do not
  // bind it.
  if (layout && !trace.oracle) {
    ZM_RETURN_IF_ERROR(CheckLayoutMergeModelOptions(model, options.cut, options.rules));
  }
  const double res = grid.resolution_m;
  Segmentation seg;
  try {
    // A robot's grid is cut with fewer kinds of line than a clean plan (CutOptions::
    // layout_rough_*); the model learns which cut made its pieces (the map_rough_cut feature).
    seg.rough_face_share = GridRoughFaceShare(grid);
    seg.rough_cut = layout && seg.rough_face_share > options.cut.layout_rough_face_share;
    Pieces pieces = CutPieces(grid, layout ? LayoutPieceCut(options.cut, seg.rough_cut)
                                           : options.cut);
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
      in.free = grid.cells(box) == kCellFree;
      // A corridor's pieces, joined where it runs on: for the grids the robot half merges
      // (above the compiled-in model's gate), whose corridors the cut crosses at every door
      // jamb; plans and scans keep the plan trees' zones. Before the model, a corridor's pieces
      // hold no room yet; after it, some do (issue 28, fifteenth and sixteenth rounds).
      const bool channels = seg.rough_face_share > kChannelRoughFaceShare;
      const bool channels_first = options.learned.layout_channel_before_model == 1.0;
      if (channels && channels_first) {
        in.count = MergeChannels(&labels, in.free, in.count, res,
                                 options.learned.layout_channel_depth_m,
                                 options.learned.layout_channel_min_width_m,
                                 options.learned.layout_channel_median_width_ratio);
      }
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
      in.rough_cut = seg.rough_cut;
      ZM_ASSIGN_OR_RETURN(
          const int merged,
          MergeLayoutPieces(in, model, options.learned.layout_merge_threshold, trace));
      // Specks and slivers the model left alone (a laser map's stray free cells) are no zone
      // of their own, as in the rule merges.
      count = MergeSmallSegments(
          &labels, merged, static_cast<int>(options.learned.layout_min_area_m2 / (res * res)));
      count = MergeCorridors(&labels, pieces.dt, count, res, options.kinds,
                             options.learned.layout_corridor_border_ratio,
                             options.learned.layout_corridor_width_ratio);
      if (channels && !channels_first) {
        count = MergeChannels(&labels, in.free, count, res,
                              options.learned.layout_channel_depth_m,
                              options.learned.layout_channel_min_width_m,
                              options.learned.layout_channel_median_width_ratio);
      }
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
