// Automatic semantic zones from a 2-D occupancy grid (room segmentation), from the keyframe
// graph alone, and their scoring against a hand-made ground truth (docs/segmentation.md).
//
// Room segmentation, in order: clean the grid (declutter by wall directions, close wall gaps
// narrower than `wall_gap_close_m`, drop free specks and laser rays thinner than `ray_width_m`,
// turn small clutter islands inside free space into free space); the layout: doorways (gaps
// between collinear walls up to a door's width) and openings (thin walls continued from a free
// end to the next wall, up to `opening_max_width_m`, or to a collinear wall end facing it up to
// `facing_opening_max_width_m`; the facade across a protrusion's mouth; the mouth between two
// aligned wall ends), declutter.h; distance transform of free
// space with both closed; room seeds from a hierarchy of thresholds of that transform: a
// component at one level is replaced by its children at a higher level only when at least two
// of them are room-sized (so each doorway is cut at its own level, not at one global
// threshold); seeds grow back over free space by a priority flood on the distance transform (a
// watershed, so borders settle on the narrowest place: a door, a closed doorway or opening);
// neighbours split only by an opening that constricts neither (`opening_merge_ratio` of the
// larger one's peak clearance, and the border's main opening open over `opening_local_ratio`
// of the space beside it) merge again (a corridor crossed by an aligned wall); neighbours
// whose shared border is an opening wider than any door (`merge_min_opening_m`) and not a
// constriction relative to them (`merge_open_border_ratio`) merge (one open room cut in two by
// clutter); segments smaller than `min_room_area_m2` merge into the neighbour sharing the
// longest border; each segment is labelled corridor when long and narrow, else room.
// Those merges are "the rule merges". By default (`layout_merge_threshold` > 0) the pieces are
// cut with every thin wall end continued across the building and no rule merge, and the learned
// layout merge (layout_merge.h) joins them, with the rule merges' segmentation of the same grid
// as one of its inputs.
//
// Invariants of a Segmentation: labels is CV_32SC1 of the grid's size; 0 = no zone, 1..N =
// segments[label - 1]; every labelled cell is free in the cleaned grid; each segment is one
// 4-connected region.
#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <span>
#include <string>
#include <vector>

#include "common/status.h"
#include "zones/grid_map.h"
#include "zones/layout_merge.h"
#include "zones/zone_set.h"

namespace zm {

struct SegmentOptions {
  double wall_gap_close_m = 0.45;       // gaps in walls up to this width are closed
  double ray_width_m = 0.15;            // free strands thinner than this are dropped
  double clutter_area_m2 = 0.5;         // obstacle islands smaller than this become free
  double wall_min_length_m = 1.0;       // decluttering: an island of obstacles or unknown cells
                                        // with no straight run this long along the dominant wall
                                        // directions becomes free (declutter.h); 0 = off
  double wall_line_gap_m = 0.45;        // collinear pieces this close form one run (dashed walls)
  double wall_stub_min_length_m = 0.3;  // a straight piece this long, joined to a wall and
                                        // seen free on both sides (a wall between two doors),
                                        // bounds doorways and openings like a wall run
                                        // (declutter.h; 0 = off). Physical, fixed (issue 16,
                                        // third part)
  double door_max_width_m = 1.2;        // a gap up to this wide between two collinear wall runs
                                        // is a door: closed while seeds are found (0 = off). At
                                        // most the narrowest corridor (1.2 m), so room walls
                                        // aligned across a corridor never close it
  double opening_max_width_m = 3.0;     // layout: a thin wall run ending in free space is
                                        // continued along its direction to the next wall at most
                                        // this far away (declutter.h); seeds are found with these
                                        // openings closed (0 = off). Physical: a sliding partition
                                        // or open-plan opening between two rooms is up to 3 m
  double facade_opening_max_width_m = 3.0;  // layout: the exterior wall continued across a
                                            // protrusion's mouth up to this wide (a balcony behind
                                            // a full-width slider, a bay; declutter.h; 0 = off), an
                                            // opening like the others. Physical, the opening width
  double facing_opening_max_width_m = 4.0;  // layout: a free wall end is continued beyond the
                                            // opening width, up to this far, only to the free end
                                            // of a collinear wall facing it (one wall with a wide
                                            // sliding door; declutter.h; 0 = off)
  double mouth_opening_max_width_m = 3.0;  // layout: the line between the aligned free ends of
                                           // two parallel walls up to this far apart (a closet or
                                           // wardrobe whose front is one door; declutter.h; 0 =
                                           // off), an opening like the others
  double corner_opening_max_width_m = 0.0;  // layout: a thin wall ending at a corner or a T is
                                            // continued past it into free space up to this far
                                            // (declutter.h; 0 = off), an opening like the others
  double cap_opening_max_width_m = 0.0;     // layout: the line across a thin wall's free end,
                                            // perpendicular to it, to the next wall up to this far
                                            // (declutter.h; 0 = off), an opening like the others
  double opening_wall_max_thickness_m = 0.3;  // ...from the free end of a wall at most this
                                              // thick (interior partitions are 0.1-0.25 m): the
                                              // face of a block or a corner is no free end
  double opening_merge_ratio = 0.6;        // ...and the two segments an opening separates merge
                                           // again when its clearance is >= this x the LARGER one's
                                           // peak clearance: it constricts neither (a corridor
                                           // crossed by an aligned wall). Leave-one-out pick
  double opening_local_ratio = 0.75;       // ...and only when the opening line is open over >=
                                           // this share of the free width just either side of it
                                           // (declutter.h, OpeningLine::Constriction; 0 = off); an
                                           // opening no wider than a door never merges. Fixed
  double opening_side_depth_m = 1.0;       // ...measured up to this far either side of the opening
  double seed_min_level_m = 0.35;          // lowest distance-transform level tried for seeds
  double seed_level_step_m = 0.05;         // step between levels
  double seed_max_level_m = 3.0;           // highest level tried
  double seed_min_area_m2 = 0.6;           // a child at a level counts when at least this big...
  double seed_min_persistence_m = 0.3;     // ...and rises this far above the level it split at
  double seedless_room_min_area_m2 = 0.5;  // a space enclosed by walls, doors and openings
                                           // that no seed reached (narrower than the lowest level:
                                           // a closet) is a segment of its own from this area on,
                                           // instead of flooded from a neighbour (0 = off). Fixed
  double merge_open_border_ratio = 0.45;   // neighbours merge when their border's clearance is
                                           // >= this x the smaller one's peak clearance (0 = off)
  double merge_min_opening_m = 2.4;        // ...and the opening is wider than any door (a double
                                           // door with its frame is < 2.4 m)
  double merge_no_constriction_ratio = 0.0;  // neighbours also merge, however narrow, when the
                                             // border is >= this x the narrower one's peak
                                             // clearance: no constriction, one space (a corridor
                                             // cut at a side opening); 0 = off
  double min_room_area_m2 = 0.5;       // smaller segments merge into a neighbour (0.5 m2: a
                                       // closet; fixed in the third part, was 1 m2, a WC)
  double corridor_elongation = 4.0;    // length / width at or above this = corridor
  double corridor_max_width_m = 3.5;   // corridors are at most this wide
  double simplify_tolerance_m = 0.10;  // approxPolyDP tolerance for polygons

  // The learned layout merge (layout_merge.h; issue 16, fifth and sixth parts). When on, free
  // space is cut into layout pieces (every thin wall end continued up to `layout_line_max_m`,
  // mouths and facades as below, thin walls continued past corners and T's and free ends capped
  // across, enclosed spaces from `layout_seedless_min_area_m2`, no rule merges) and
  // the compiled-in model merges neighbouring pieces while its probability that they are one
  // room is >= the threshold. 0 = off: the rule merges above decide, as before.
  double layout_merge_threshold = 0.4;
  double layout_line_max_m = 20.0;
  double layout_mouth_max_m = 6.0;
  double layout_facade_max_m = 8.0;
  double layout_corner_max_m = 3.0;  // (sixth part) walls continued past corners and T's...
  double layout_cap_max_m = 3.5;     // ...and free ends capped across (declutter.h)
  double layout_seedless_min_area_m2 = 0.2;
  double layout_min_area_m2 = 0.1;  // ...and segments it leaves smaller than this merge into
                                    // the neighbour sharing the longest border (specks;
                                    // 0.5 m2 as the rule merges costs 1-5 IoU points on the
                                    // apartments: their closets are 0.5-1 m2)
};

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
  double runtime_ms = 0.0;
};

// Sets one field of `options` from "KEY=VALUE" (KEY is the field name, VALUE a number in the
// field's unit). An unknown key or a value that is not a finite number is an InvalidArgument
// naming it. For evaluation runs (leave-one-out parameter choice); the defaults are the product.
[[nodiscard]] Status SetSegmentOption(const std::string& key_value, SegmentOptions* options);

// Segments the grid into rooms and corridors. Errors: empty grid, bad options, OpenCV failure.
// The first form uses the compiled-in layout merge model; the second takes another one (a model
// being trained or evaluated) and a trace (training data; layout_merge.h).
[[nodiscard]] Result<Segmentation> SegmentRooms(const OccupancyGrid& grid,
                                                const SegmentOptions& options = {});
[[nodiscard]] Result<Segmentation> SegmentRooms(const OccupancyGrid& grid,
                                                const SegmentOptions& options,
                                                const LayoutMergeModel& model,
                                                const LayoutMergeTrace& trace = {});

// Splits every segment holding more than `max_keyframes` of `positions_m` (map frame) in two
// along the principal axis of its keyframes at their median, recursively, until each part
// holds at most `max_keyframes`. Keyframes off the grid or outside every segment are ignored.
// Labels of split parts are appended; kinds are kept. max_keyframes must be >= 1.
[[nodiscard]] Status SplitOversizeSegments(const OccupancyGrid& grid,
                                           std::span<const Eigen::Vector2d> positions_m,
                                           int max_keyframes, Segmentation* seg);

// One polygon zone per segment (largest outer contour through the boundary cells' centres,
// simplified, always a simple counter-clockwise ring, in map-frame metres), named
// "<kind>_<n>", floor 0. Segments whose outline has < 3 vertices are skipped.
[[nodiscard]] Result<std::vector<Zone>> SegmentationToZones(const Segmentation& seg,
                                                            const OccupancyGrid& grid,
                                                            const SegmentOptions& options = {});

// Writes the segments as a colour PNG over the grid (occupied black, unknown grey, free but in
// no segment white, each segment one colour): for looking at a result, not for reading back.
[[nodiscard]] Status WriteSegmentationPng(const std::string& path, const OccupancyGrid& grid,
                                          const Segmentation& seg);

// GeoJSON FeatureCollection of Polygon features (closed rings, metres) with properties name,
// kind, floor: the zones module's zone file format.
[[nodiscard]] std::string ZonesToGeoJson(std::span<const Zone> zones);
[[nodiscard]] Status WriteZonesGeoJson(const std::string& path, std::span<const Zone> zones);

// Zones from keyframe positions alone (no grid): keyframes are bucketed into square cells of
// `cell_size_m`; a cell holding more than `max_keyframes` is split along the principal axis of
// its keyframes at the median, recursively. Each part becomes one zone: the convex hull of its
// keyframes grown by `margin_m`, clipped to its cell part, so zones never overlap and each
// contains its keyframes. Zones are named "area_<n>", kind "room".
struct KeyframeZoneOptions {
  double cell_size_m = 8.0;
  int max_keyframes = 200;
  double margin_m = 0.5;
};
[[nodiscard]] Result<std::vector<Zone>> ZonesFromKeyframes(
    std::span<const Eigen::Vector2d> positions_m, const KeyframeZoneOptions& options = {});

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
  int gt_rooms = 0;
  int predicted_segments = 0;
};

// Scores `predicted` against `ground_truth` (both CV_32SC1, 0 = none) over their common top-left
// size (a map and its ground truth can differ by a pixel). Precision and recall count only cells
// that are in some GT room and in some predicted segment (ROSE² evaluation); mean_iou counts the
// same cells, mean_iou_full all cells of both (free cells the GT leaves out, GT cells that are
// not free in the map). Errors on a wrong type.
[[nodiscard]] Result<SegmentationScore> ScoreSegmentation(const cv::Mat& predicted,
                                                          const cv::Mat& ground_truth);

}  // namespace zm
