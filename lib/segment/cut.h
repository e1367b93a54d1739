// The cut stage of room segmentation: the occupancy grid's free space cleaned and cut into
// pieces, each grown from one seed (docs/segmentation.md; the method is in segmentation.h).
//
// Clean the grid (declutter by wall directions, close wall gaps narrower than
// `wall_gap_close_m`, drop free specks and laser rays thinner than `ray_width_m`, turn small
// clutter islands inside free space into free space); find the layout (doorways: gaps between
// collinear walls up to a door's width; openings: thin walls continued from a free end to the
// next wall, up to `opening_max_width_m`, or to a collinear wall end facing it up to
// `facing_opening_max_width_m`; the facade across a protrusion's mouth; the mouth between two
// aligned wall ends; declutter.h); distance transform of free space with both closed; room seeds
// from a hierarchy of thresholds of that transform (a component at one level is replaced by its
// children at a higher level only when at least two of them are room-sized, so each doorway is
// cut at its own level, not at one global threshold); seeds grow back over free space by a
// priority flood on the distance transform (a watershed, so borders settle on the narrowest
// place: a door, a closed doorway or opening).
#pragma once

#include <opencv2/core/mat.hpp>
#include <span>

#include "common/status.h"
#include "segment/declutter.h"
#include "segment/grid_map.h"
#include "segment/option_field.h"

namespace zm {

struct CutOptions {
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
  double mouth_opening_max_width_m = 3.0;   // layout: the line between the aligned free ends of
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
  double opening_side_depth_m = 1.0;          // an opening's constriction (declutter.h) is measured
                                              // up to this far either side of it
  double opening_end_min_extent_m = 0.0;      // (issue 28, fourth round) a wall end whose
                                              // occupied component spans less than this along
                                              // both wall directions (a clutter block, a loose
                                              // leaf) starts no opening, corner continuation,
                                              // cap or mouth (declutter.h; 0 = off)
  double seed_min_level_m = 0.35;             // lowest distance-transform level tried for seeds
  double seed_level_step_m = 0.05;            // step between levels
  double seed_max_level_m = 3.0;              // highest level tried
  double seed_min_area_m2 = 0.6;              // a child at a level counts when at least this big...
  double seed_min_persistence_m = 0.3;        // ...and rises this far above the level it split at
  double seedless_room_min_area_m2 = 0.5;     // a space enclosed by walls, doors and openings
                                           // that no seed reached (narrower than the lowest level:
                                           // a closet) is a piece of its own from this area on,
                                           // instead of flooded from a neighbour (0 = off). Fixed

  // The layout pieces the learned merge joins (issue 16, fifth and sixth parts; segmentation.h):
  // every thin wall end continued up to `layout_line_max_m`, mouths and facades as below, thin
  // walls continued past corners and T's and free ends capped across, enclosed spaces from
  // `layout_seedless_min_area_m2` (LayoutPieceCut).
  double layout_line_max_m = 20.0;
  double layout_mouth_max_m = 6.0;
  double layout_facade_max_m = 8.0;
  double layout_corner_max_m = 3.0;      // (sixth part) walls continued past corners and T's...
  double layout_cap_max_m = 3.5;         // ...and free ends capped across (declutter.h)
  double layout_end_min_extent_m = 0.0;  // (fourth round) opening_end_min_extent_m of the layout
                                         // pieces
  double layout_seedless_min_area_m2 = 0.2;
  // (issue 28, eighth round) A robot's grid: when more than `layout_rough_face_share` of the
  // grid's wall faces are rough (GridFaceShares::rough, measured on the grid before any
  // cleaning), its layout pieces are cut with the two lengths below instead of
  // layout_corner_max_m and layout_cap_max_m. Corners and caps were added for the closets of
  // clean plans; a SLAM grid's noise, leaves and clutter make a free wall end or a corner at
  // every bump. 1 = no grid is rough (every share is at most 1).
  double layout_rough_face_share = 1.0;
  double layout_rough_corner_max_m = 3.0;
  double layout_rough_cap_max_m = 3.5;
};

// The fields by name, in the order of `--param` and of a layout merge model's record.
inline constexpr OptionField<CutOptions> kCutOptionFields[] = {
    {"wall_gap_close_m", &CutOptions::wall_gap_close_m},
    {"ray_width_m", &CutOptions::ray_width_m},
    {"clutter_area_m2", &CutOptions::clutter_area_m2},
    {"wall_min_length_m", &CutOptions::wall_min_length_m},
    {"wall_line_gap_m", &CutOptions::wall_line_gap_m},
    {"door_max_width_m", &CutOptions::door_max_width_m},
    {"opening_max_width_m", &CutOptions::opening_max_width_m},
    {"facade_opening_max_width_m", &CutOptions::facade_opening_max_width_m},
    {"mouth_opening_max_width_m", &CutOptions::mouth_opening_max_width_m},
    {"facing_opening_max_width_m", &CutOptions::facing_opening_max_width_m},
    {"corner_opening_max_width_m", &CutOptions::corner_opening_max_width_m},
    {"cap_opening_max_width_m", &CutOptions::cap_opening_max_width_m},
    {"opening_end_min_extent_m", &CutOptions::opening_end_min_extent_m},
    {"opening_wall_max_thickness_m", &CutOptions::opening_wall_max_thickness_m},
    {"wall_stub_min_length_m", &CutOptions::wall_stub_min_length_m},
    {"opening_side_depth_m", &CutOptions::opening_side_depth_m},
    {"seedless_room_min_area_m2", &CutOptions::seedless_room_min_area_m2},
    {"seed_min_level_m", &CutOptions::seed_min_level_m},
    {"seed_level_step_m", &CutOptions::seed_level_step_m},
    {"seed_max_level_m", &CutOptions::seed_max_level_m},
    {"seed_min_area_m2", &CutOptions::seed_min_area_m2},
    {"seed_min_persistence_m", &CutOptions::seed_min_persistence_m},
    {"layout_line_max_m", &CutOptions::layout_line_max_m},
    {"layout_mouth_max_m", &CutOptions::layout_mouth_max_m},
    {"layout_facade_max_m", &CutOptions::layout_facade_max_m},
    {"layout_corner_max_m", &CutOptions::layout_corner_max_m},
    {"layout_cap_max_m", &CutOptions::layout_cap_max_m},
    {"layout_end_min_extent_m", &CutOptions::layout_end_min_extent_m},
    {"layout_seedless_min_area_m2", &CutOptions::layout_seedless_min_area_m2},
    {"layout_rough_face_share", &CutOptions::layout_rough_face_share},
    {"layout_rough_corner_max_m", &CutOptions::layout_rough_corner_max_m},
    {"layout_rough_cap_max_m", &CutOptions::layout_rough_cap_max_m},
};

// An InvalidArgument naming the first option out of its range.
[[nodiscard]] Status CheckCutOptions(const CutOptions& o);

// How a grid's free space meets what is not free, counted over the edges between a free cell and
// a cell that is not (4-neighbours; outside the image counts as unknown). A plan drawn by hand
// has straight wall faces and is walled all round; a robot's grid has noise, clutter and
// unexplored gaps.
struct GridFaceShares {
  double rough = 0.0;           // of the edges facing an occupied cell (a wall face), the share
                                // whose face does not continue straight: the two cells beside
                                // this one, across the edge, are not both free with an occupied
                                // cell beyond them
  double unknown_border = 0.0;  // of all such edges, the share facing neither a free nor an
                                // occupied cell (unexplored, or a gap)
};
// `free` and `occupied`: CV_8UC1 of one size, nonzero = free / occupied.
[[nodiscard]] GridFaceShares MeasureGridFaces(const cv::Mat& free, const cv::Mat& occupied);

// The grid's rough face share as read (free and occupied cells, before any cleaning): the
// quantity layout_rough_face_share is compared with.
[[nodiscard]] double GridRoughFaceShare(const OccupancyGrid& grid);

// The options the layout pieces are cut with: every thin wall end continued across the building,
// wide mouths and facades, small enclosed spaces their own pieces; on a rough grid (its
// GridRoughFaceShare above layout_rough_face_share) corners and caps as
// layout_rough_corner_max_m and layout_rough_cap_max_m say.
[[nodiscard]] CutOptions LayoutPieceCut(const CutOptions& o, bool rough_grid = false);

// Free space cut into pieces, inside `box` (the bounding box of free space plus a border; every
// image but free_cleaned and walls is of the box's size).
struct Pieces {
  cv::Mat free_cleaned;  // CV_8UC1 of the grid's size, 255 where the cleaned grid is free
  WallEvidence walls;    // of the grid's size
  cv::Rect box;          // empty when there is no free space (then nothing below is set)
  cv::Mat labels;        // CV_32SC1, pieces 1..count, 0 = none
  int count = 0;
  cv::Mat dt;         // CV_32F clearance with doorways closed and openings open
  cv::Mat dt_closed;  // ...and with openings closed too (seeds and floods)
  cv::Mat openings;   // CV_8UC1, opening cells inside free space with doorways closed
};

// Cuts the grid's free space (checked: CV_8UC1, resolution > 0) into pieces. OpenCV exceptions
// propagate (SegmentRooms turns them into a Status).
[[nodiscard]] Pieces CutPieces(const OccupancyGrid& grid, const CutOptions& o);

// Metres to whole cells, rounded, at least 0.
[[nodiscard]] int CellsFromMetres(double m, double resolution_m);

}  // namespace zm
