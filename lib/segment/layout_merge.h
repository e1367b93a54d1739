// Learned merging of layout pieces into rooms (issue 16, fifth part; docs/segmentation.md).
//
// The layout step cuts free space into pieces along every wall, doorway and wall line continued
// across the building (declutter.h with long continuations). Most pieces are parts of a room;
// which neighbours belong together is decided here, greedily: the pair of neighbouring pieces
// the model gives the highest probability of being one room is merged, the pair's neighbours'
// features are updated, and so on until no pair reaches the threshold. The model is a small
// gradient-boosted tree ensemble over features of the two pieces and of their shared border
// (how much of it is open, how much wall lies between them, clearance, shape); it was trained by
// scripts/train_layout_merge.py on merge traces of R2V plans with known rooms, never on the
// buildings it is scored on, and is compiled in (layout_merge_model.inc).
//
// Offline only (segmentation runs before a robot's mission); it allocates freely.
#pragma once

#include <array>
#include <cstdio>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "common/status.h"
#include "segment/cut.h"
#include "segment/merge.h"

namespace zm {

// The features of a pair of neighbouring pieces, S the smaller (by area), L the larger; lengths
// in metres, areas in m2. The order is the model's input order.
inline constexpr int kLayoutFeatureCount = 47;
// One feature, or one family, per line with its meaning.
// clang-format off
inline constexpr std::array<const char*, kLayoutFeatureCount> kLayoutFeatureNames = {
    "open_m",          // free border between them (4-neighbour cell edges x resolution)
    "wall_m",          // wall between them: cells where a ray across an occupied run of at most
                       // 0.35 m lands in the other piece, counted from both sides, halved
    "open_fraction",   // open / (open + wall)
    "area_s", "area_l",
    "peak_s", "peak_l",  // largest clearance inside each (distance to anything not a piece)
    "contact_clearance",  // largest clearance on the border
    "contact_over_peak_s", "contact_over_peak_l",
    "open_over_perimeter_s", "wall_over_perimeter_s",
    "open_perimeter_share_s",  // share of S's perimeter that touches any other piece
    "open_over_extent_max_s", "open_over_extent_min_s",  // extents along the wall directions
    "rectangularity_s", "rectangularity_l", "rectangularity_union",
    "rectangularity_gain",  // union's minus the larger of the two
    "end_support_min", "end_support_max",  // share of the 0.4 m beyond each end of the border,
                                           // along its line, that is wall (a door in a wall: 1)
    "border_straightness_m",  // thickness of the border across its line
    "elongation_s", "elongation_l", "elongation_union",  // long over short extent
    "rule_same_segment",  // 1 when most of both pieces lie in one segment of the rule merges
    "rule_open_share",    // share of the border's edges the rule merges do not keep as a border
    "map_free_m2",        // the building's scale: all pieces' area (a flat, an office floor)
    "map_rule_segment_m2",  // ...and its rule segments' mean area
    "doorway_share",      // share of the border's edges on a doorway (a gap in a wall)...
    "free_end_share", "corner_share", "mouth_share", "facade_share", "cap_share",  // ...or on
                          // an opening of that kind (declutter.h, OpeningKind)
    // How clean the grid is (issue 28, fifth round), the same for every pair of a map: a plan
    // drawn by hand has straight wall faces and no loose occupied cells; a robot's grid has
    // noise, clutter, leaves and unexplored gaps. Occupied components are 8-connected cells of
    // `occupied`; their extent is the larger side of their bounding box.
    "map_specks_per_100m2",  // occupied components of extent <= 0.25 m per 100 m2 of pieces
    "map_blobs_per_100m2",   // ...of extent 0.25-1.5 m (clutter, leaves, wall fragments)
    "map_loose_occupied_share",  // share of occupied cells in components of extent <= 1.5 m
    "map_rough_face_share",  // share of wall-face edges (a free cell beside an occupied one)
                             // whose face does not continue straight on both sides
    "map_unknown_border_share",  // share of the free cells' border edges that face neither
                                 // a free nor an occupied cell (unexplored, or a gap)
    "map_rough_cut",  // (eighth round) 1 when the pieces were cut with the rough-grid options
                      // (CutOptions::layout_rough_*), else 0: a model joined from a clean-plan
                      // and a robot-grid half chooses its half by it (gate_layout_merge.py)
    // Whether a corridor runs on through the border (issue 28, eighteenth round): on each side,
    // the median over kChannelDepthM of the free run along the border's line through the
    // centre (0 where the centre is not free) over the border's length, capped at
    // kChannelRatioCap. A corridor cut across keeps about 1 on both sides, a branch meeting its
    // spine on one, a door opens wider on both; open doors in a corridor's walls move a median
    // less than they break a wall test (the seventeenth round's).
    "channel_width_near",  // the side whose ratio is nearer 1
    "channel_width_far",   // the other side
    // What the border ends at (issue 28, twentieth round): at each end, the extent (larger side
    // of the bounding box) of the 8-connected occupied component of the first occupied cell
    // end_support_* finds, capped at 8 m; 0 where nothing is occupied there. A door's jambs
    // are walls that run on for metres; in a robot's grid of a flat, a gap beside a table, a
    // cabinet or a sofa ends at about a metre of furniture.
    "end_extent_min_m", "end_extent_max_m",
    // Whether the two see each other (issue 28, twenty-eighth round). A room cut by clutter or a
    // noisy wall face is still one open space: from most of one piece most of the other is in
    // sight. Two rooms see each other only through their door. Each piece is sampled on a 0.5 m
    // lattice (at most 16 cells; a piece too small for the lattice by its clearance peak), each
    // sample weighted by its share of the piece's area. A line of sight is a straight line
    // through nothing but free cells, pieces and occupied components of extent <= 1.5 m
    // (clutter, which a robot sees past); unknown cells and walls block it. Samples farther
    // than 15 m apart count as unseen.
    "visibility",    // share of the area-weighted sample pairs (one in S, one in L) in sight
    "visibility_s",  // share of S's area whose sample sees some sample of L
};
// clang-format on

// A binary gradient-boosted tree ensemble: p = sigmoid(init + rate * sum of leaf values).
struct LayoutMergeModel {
  struct Tree {
    std::vector<int> feature;       // split feature per node, -1 at a leaf
    std::vector<double> threshold;  // go left when x[feature] <= threshold (as scikit-learn)
    std::vector<int> left, right;
    std::vector<float> value;  // leaf value
  };
  double init = 0.0;
  double rate = 0.1;
  std::vector<Tree> trees;
  // The options its training pieces were made with: the cut (the pieces themselves) and the rule
  // merges (their segmentation is two of the features). Other options give the model pieces and
  // features it never saw, so SegmentRooms refuses them (CheckLayoutMergeModelOptions).
  CutOptions cut;
  RuleMergeOptions rule_merge;

  [[nodiscard]] double Probability(const std::array<float, kLayoutFeatureCount>& x) const;
  // Whether some tree splits on feature `index` (a costly feature is computed only then).
  [[nodiscard]] bool Uses(int index) const;
};

// Parses a model from its JSON text ({"features":[names], "init", "learning_rate",
// "trees":[{"feature","threshold","left","right","value"}], "trained_with":{"cut":{...},
// "rule_merge":{...}}}); the feature names must be kLayoutFeatureNames in order (a model of
// an earlier version may list only the first of them: its trees use no later one), and
// trained_with must give every field of kCutOptionFields and kRuleMergeOptionFields by name and
// nothing else. Errors name what is wrong.
[[nodiscard]] Result<LayoutMergeModel> ParseLayoutMergeModel(const std::string& json_text);
[[nodiscard]] Result<LayoutMergeModel> LoadLayoutMergeModel(const std::string& path);
// The compiled-in model (parsed once).
[[nodiscard]] const LayoutMergeModel& DefaultLayoutMergeModel();

// The "trained_with" object of a model trained on pieces made with these options (JSON text):
// `zonemap zones segment --merge-trace --json` reports it, and scripts/train_layout_merge.py
// writes it into the model it trains.
[[nodiscard]] std::string LayoutMergeTrainedWithJson(const CutOptions& cut,
                                                     const RuleMergeOptions& rules);
// InvalidArgument naming the first option that differs from what `model` was trained with.
[[nodiscard]] Status CheckLayoutMergeModelOptions(const LayoutMergeModel& model,
                                                  const CutOptions& cut,
                                                  const RuleMergeOptions& rules);

// For training and evaluation: a ground truth to label each pair with (same room or not) and a
// CSV to write every pair's features at every merge step; with `oracle`, the merges follow the
// ground truth (a random pair of the same room each step) instead of the model.
struct LayoutMergeTrace {
  const cv::Mat* ground_truth = nullptr;  // CV_32SC1, 0 = no room; the grid's size
  std::FILE* csv = nullptr;
  bool oracle = false;
};

struct LayoutMergeInputs {
  cv::Mat* labels = nullptr;  // CV_32SC1 pieces 1..count, 0 = none; merged in place
  int count = 0;
  cv::Mat occupied;  // CV_8UC1, nonzero = wall or obstacle; labels' size
  double resolution_m = 0.05;
  double wall_angle_rad = 0.0;  // the dominant wall direction (extents are taken along it)
  cv::Point offset;             // where labels' (0, 0) lies in the ground truth
  cv::Mat rule_labels;          // CV_32SC1, labels' size: the same free space segmented by the
                                // rule merges (SegmentOptions with layout_merge_threshold 0); its
                                // opinion is two features. Empty: both features 0
  cv::Mat doorways;             // CV_8UC1, labels' size, nonzero = doorway cell; may be empty
  cv::Mat opening_kinds;        // CV_8UC1, labels' size, OpeningKind bits; may be empty
  cv::Mat free;                 // CV_8UC1, labels' size, nonzero = a free cell of the grid (the
                                // wall-face and unknown-border features); empty: the pieces
  bool rough_cut = false;       // the pieces were cut with the rough-grid options (a feature)
};

// Merges pieces greedily while the best pair's probability is >= threshold; returns the number
// of labels afterwards (relabelled 1..n in order of first appearance of their smallest piece).
[[nodiscard]] Result<int> MergeLayoutPieces(const LayoutMergeInputs& in,
                                            const LayoutMergeModel& model, double threshold,
                                            const LayoutMergeTrace& trace = {});

}  // namespace zm
