// Automatic semantic zones from a 2-D occupancy grid: room segmentation, offline (before a
// robot's mission; it allocates freely). docs/segmentation.md has the method and its scores.
//
// One stage per file: cut.h (free space cleaned and cut into pieces), merge.h (pieces joined
// by the rule merges) or layout_merge.h (by the learned model), split.h (segments capped by
// keyframe count), write.h (polygons, GeoJSON, a PNG to look at), score.h (against a ground
// truth). Each stage takes its own options struct; SegmentOptions is all of them.
//
// By default (`learned.layout_merge_threshold` > 0) the pieces are cut with every thin wall end
// continued across the building (LayoutPieceCut) and no rule merge, and the learned layout merge
// joins them, with the rule merges' segmentation of the same grid as one of its inputs. The model
// records the options its training pieces were cut with; other cut or rule-merge options are
// refused (layout_merge.h, CheckLayoutMergeModelOptions).
#pragma once

#include <cstdint>

#include "common/status.h"
#include "segment/cut.h"
#include "segment/grid_map.h"
#include "segment/layout_merge.h"
#include "segment/merge.h"
#include "segment/segment_info.h"
#include "segment/write.h"

namespace zm {

struct SegmentOptions {
  CutOptions cut;
  RuleMergeOptions rules;
  LearnedMergeOptions learned;
  KindOptions kinds;
  OutlineOptions outline;
};

// Room segmentation runs on the known part of a grid (the bounding box of its free and occupied
// cells, with a rim of kKnownRimM of unknown ones: wall continuations and the outside's facade
// tests look up to 8 m beyond a wall), and refuses one larger than kMaxSegmentCells: 30 million
// cells (a floor of 270 x 270 m at 0.05 m), all free, peaked at 2.0 GB and 37 s of CPU
// (docs/segmentation.md, "Bad input"); the Jetson shares 8 GB with a model.
inline constexpr double kKnownRimM = 10.0;
inline constexpr std::int64_t kMaxSegmentCells = 30'000'000;

// An InvalidArgument naming the first option out of its range.
[[nodiscard]] Status CheckSegmentOptions(const SegmentOptions& options);

// Segments the grid into rooms and corridors. Errors: empty grid, bad options, a model trained
// on other cut options, OpenCV failure. The first form uses the compiled-in layout merge model;
// the second takes another one (a model being trained or evaluated) and a trace (training data;
// layout_merge.h).
[[nodiscard]] Result<Segmentation> SegmentRooms(const OccupancyGrid& grid,
                                                const SegmentOptions& options = {});
[[nodiscard]] Result<Segmentation> SegmentRooms(const OccupancyGrid& grid,
                                                const SegmentOptions& options,
                                                const LayoutMergeModel& model,
                                                const LayoutMergeTrace& trace = {});

}  // namespace zm
