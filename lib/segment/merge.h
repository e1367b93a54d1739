// The merge stage of room segmentation: pieces (cut.h) joined into rooms and corridors, by the
// rule merges or by the learned layout merge (layout_merge.h), and each segment's kind.
//
// The rule merges, in order: neighbours split only by an opening that constricts neither
// (`opening_merge_ratio` of the larger one's peak clearance, and the border's main opening open
// over `opening_local_ratio` of the space beside it) merge again (a corridor crossed by an aligned
// wall); neighbours whose shared border is an opening wider than any door
// (`merge_min_opening_m`) and not a constriction relative to them (`merge_open_border_ratio`)
// merge (one open room cut in two by clutter); segments smaller than `min_room_area_m2` merge into
// the neighbour sharing the longest border. Each segment is then labelled corridor when long and
// narrow, else room.
#pragma once

#include <opencv2/core/mat.hpp>
#include <vector>

#include "common/status.h"
#include "segment/cut.h"
#include "segment/option_field.h"
#include "segment/segment_info.h"

namespace zm {

struct RuleMergeOptions {
  double opening_merge_ratio = 0.6;       // two segments an opening separates merge again when its
                                          // clearance is >= this x the LARGER one's peak clearance:
                                          // it constricts neither (a corridor crossed by an aligned
                                          // wall). Leave-one-out pick
  double opening_local_ratio = 0.75;      // ...and only when the opening line is open over >= this
                                          // share of the free width just either side of it
                                          // (declutter.h, OpeningLine::Constriction; 0 = off); an
                                          // opening no wider than a door never merges. Fixed
  double merge_open_border_ratio = 0.45;  // neighbours merge when their border's clearance is
                                          // >= this x the smaller one's peak clearance (0 = off)
  double merge_min_opening_m = 2.4;       // ...and the opening is wider than any door (a double
                                          // door with its frame is < 2.4 m)
  double merge_no_constriction_ratio = 0.0;  // neighbours also merge, however narrow, when the
                                             // border is >= this x the narrower one's peak
                                             // clearance: no constriction, one space (a corridor
                                             // cut at a side opening); 0 = off
  double min_room_area_m2 = 0.5;  // smaller segments merge into a neighbour (0.5 m2: a closet;
                                  // fixed in the third part, was 1 m2, a WC)
};

inline constexpr OptionField<RuleMergeOptions> kRuleMergeOptionFields[] = {
    {"opening_merge_ratio", &RuleMergeOptions::opening_merge_ratio},
    {"opening_local_ratio", &RuleMergeOptions::opening_local_ratio},
    {"merge_open_border_ratio", &RuleMergeOptions::merge_open_border_ratio},
    {"merge_min_opening_m", &RuleMergeOptions::merge_min_opening_m},
    {"merge_no_constriction_ratio", &RuleMergeOptions::merge_no_constriction_ratio},
    {"min_room_area_m2", &RuleMergeOptions::min_room_area_m2},
};

// The learned layout merge (layout_merge.h; issue 16, fifth and sixth parts). When on, the
// pieces are cut with LayoutPieceCut and the model merges neighbouring pieces while its
// probability that they are one room is >= the threshold. 0 = off: the rule merges decide.
struct LearnedMergeOptions {
  double layout_merge_threshold = 0.4;
  double layout_min_area_m2 = 0.1;  // segments it leaves smaller than this merge into the
                                    // neighbour sharing the longest border (specks; 0.5 m2 as
                                    // the rule merges costs 1-5 IoU points on the apartments:
                                    // their closets are 0.5-1 m2)
  // Corridor continuation (issue 28, tenth round; evaluated, not picked: docs/segmentation.md):
  // after the merges above, two neighbours of which one is a corridor (KindOptions), both no
  // wider than corridor_max_width_m, merge when their shared border is >= border_ratio x the
  // narrower one's width (cut across, not a door) and the wider is <= width_ratio x the
  // narrower (one corridor keeps its width); repeated until nothing merges. 0 = off.
  double layout_corridor_border_ratio = 0.0;
  double layout_corridor_width_ratio = 0.0;  // 0 = any widths
  // Channel joins (issue 28, fifteenth round: MergeChannels), on grids above the model's gate:
  // two neighbours join across a straight border kMaxChannelWidthM or narrower and at least
  // layout_channel_min_width_m wide when, on one side, a channel (walls beside both of the
  // border's ends, its middle free) runs on for layout_channel_depth_m. 0 = off.
  double layout_channel_depth_m = 0.0;
  double layout_channel_min_width_m = 1.2;  // narrower borders are doors
  // 1: the channel joins act on the cut's pieces, before the model merges them (issue 28,
  // sixteenth round: while a corridor's pieces hold no room yet); 0: after the model.
  double layout_channel_before_model = 0.0;
  // > 0: a side is a channel when the median, over the steps, of the free run across the normal
  // through the centre line is within [kChannelMinWidthRatio, this] x the border's length (issue
  // 28, seventeenth round: an office corridor's walls are broken by open doors, which the walls
  // test below fails on and a median passes over). 0: walls beside both ends (fifteenth round).
  double layout_channel_median_width_ratio = 0.0;
};

inline constexpr OptionField<LearnedMergeOptions> kLearnedMergeOptionFields[] = {
    {"layout_merge_threshold", &LearnedMergeOptions::layout_merge_threshold},
    {"layout_min_area_m2", &LearnedMergeOptions::layout_min_area_m2},
    {"layout_corridor_border_ratio", &LearnedMergeOptions::layout_corridor_border_ratio},
    {"layout_corridor_width_ratio", &LearnedMergeOptions::layout_corridor_width_ratio},
    {"layout_channel_depth_m", &LearnedMergeOptions::layout_channel_depth_m},
    {"layout_channel_min_width_m", &LearnedMergeOptions::layout_channel_min_width_m},
    {"layout_channel_before_model", &LearnedMergeOptions::layout_channel_before_model},
    {"layout_channel_median_width_ratio",
     &LearnedMergeOptions::layout_channel_median_width_ratio},
};

// A segment's kind: corridor when long and narrow, else room.
struct KindOptions {
  double corridor_elongation = 4.0;   // length / width at or above this = corridor
  double corridor_max_width_m = 3.5;  // corridors are at most this wide
};

inline constexpr OptionField<KindOptions> kKindOptionFields[] = {
    {"corridor_elongation", &KindOptions::corridor_elongation},
    {"corridor_max_width_m", &KindOptions::corridor_max_width_m},
};

// InvalidArgument naming the first option out of its range.
[[nodiscard]] Status CheckRuleMergeOptions(const RuleMergeOptions& o);
[[nodiscard]] Status CheckLearnedMergeOptions(const LearnedMergeOptions& o);

// Merges `pieces` by the rules above, in place; returns the number of segments, labelled 1..N.
[[nodiscard]] int MergeByRules(const RuleMergeOptions& o, double door_max_width_m,
                               double resolution_m, Pieces* pieces);

// Merges segments smaller than `min_area` cells into the neighbour sharing the longest border
// (dropping isolated ones), then renumbers labels 1..N, leaving out labels with no cells (so
// with `min_area` 0 it only numbers the segments densely). Returns N.
int MergeSmallSegments(cv::Mat* labels, int label_count, int min_area);

// Corridor continuation (LearnedMergeOptions::layout_corridor_*): merges neighbours of which one
// is a corridor (DescribeSegments' kind over `dt`), both no wider than kinds.corridor_max_width_m,
// whose shared border (4-neighbour cell pairs) is at least `border_ratio` x the narrower one's
// width and whose wider is at most `width_ratio` x the narrower (0 = any), until nothing merges;
// renumbers labels 1..N and returns N (`label_count` when border_ratio <= 0).
int MergeCorridors(cv::Mat* labels, const cv::Mat& dt, int label_count, double resolution_m,
                   const KindOptions& kinds, double border_ratio, double width_ratio);

// Channel joins (LearnedMergeOptions::layout_channel_*): merges two neighbouring segments when
// their shared border is one straight cut (its cell pairs within kChannelStraightCells of a line,
// kChannelPresence of its length present) between `min_width_m` and kMaxChannelWidthM long, and
// on at least one side a channel runs on from it: at kChannelSteps of the steps up to `depth_m`
// along the border's normal, the cell on its centre line is free in `free` and, within
// kChannelEndProbeM beyond each of its two ends, some cell is not (a wall or unknown; outside
// `free` counts as not free). A door's jambs are a wall's thickness deep; a corridor cut across,
// a branch meeting its spine or a corridor opening into a hall runs on. Joins are transitive
// (one pass over the borders as they are); renumbers labels 1..N and returns N (`label_count`
// when depth_m <= 0). `free` is CV_8UC1 of `labels`' size, nonzero = a free cell of the grid.
// With `median_width_ratio` > 0 a side is a channel instead when, over the steps up to
// `depth_m`, the median free run across the normal through the centre line (a step whose centre
// is not free counts 0) is within [kChannelMinWidthRatio, median_width_ratio] x the border's
// length: a corridor keeps its width past the doors that open its walls; a room behind a door,
// or the corridor beside one, is wider than the door.
inline constexpr double kMaxChannelWidthM = 3.0;
inline constexpr double kChannelMinWidthRatio = 0.7;
int MergeChannels(cv::Mat* labels, const cv::Mat& free, int label_count, double resolution_m,
                  double depth_m, double min_width_m, double median_width_ratio = 0.0);

// Each segment's area, width and kind from `labels` (1..count) and its clearance `dt`.
[[nodiscard]] std::vector<SegmentInfo> DescribeSegments(const cv::Mat& labels, const cv::Mat& dt,
                                                        int count, double resolution_m,
                                                        const KindOptions& o);

}  // namespace zm
