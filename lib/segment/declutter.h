// Decluttering of a laser occupancy grid before room segmentation, by dominant wall directions
// (the idea of ROSE², Luperto et al.: walls of a building run along one or two perpendicular
// directions and are long; furniture, people and scan noise are short and anywhere).
//
// 1. The dominant wall direction is the peak of the histogram of occupied-boundary gradient
//    orientations folded modulo 90 degrees (a rectilinear building has walls at theta and
//    theta + 90 degrees).
// 2. Wall evidence: occupied cells on a straight run of at least `wall_min_length_m` along theta
//    or theta + 90 degrees, where collinear pieces closer than `wall_gap_m` count as one run
//    (dashed walls: glass, laser dropouts).
//    Doorways: a gap of at most a door's width between two collinear runs is the wall continued
//    across a door; room seeds are looked for with doorways closed (segmentation.h).
//    Openings (the layout step, after ROSE²'s extended wall lines): a thin wall run that ends in
//    free space is continued along its own direction until it meets another wall run, when that
//    is at most an opening's width away (sliding partitions, open-plan openings between rooms). An
//    opening is only a candidate: segmentation.h keeps it as a border between two segments only
//    when it is narrow for at least one of them (a corridor crossed by an aligned wall is not).
// 3. Clutter: every island of non-free cells (occupied or unknown, 8-connected, not touching the
//    grid border, so not the outside of the building) holding no wall evidence is turned into
//    free space, whatever its size: furniture seen by the laser, the unknown shadow behind it, a
//    patch of floor the robot never saw inside a room. An island that holds a wall (a room block
//    in the middle of a hall, a partition) is kept.
//
// Invariants: the returned mask has the grid's size, 255 = free; it is a superset of the grid's
// free cells; cells connected to the border through non-free cells never become free.
#pragma once

#include <algorithm>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace zm {

// The dominant wall direction of `occupied` (CV_8UC1, 255 = occupied), in radians in
// [-pi/4, pi/4): walls run at this angle and at this angle + pi/2 (image x right, y down).
// 0 when there is no occupied boundary.
[[nodiscard]] double DominantWallAngle(const cv::Mat& occupied);

// One opening as a straight line through the middle of its band of cells, in grid coordinates
// (x = column, y = row, cell centres at integers), and what MeasureOpenings found around it.
struct OpeningLine {
  cv::Point2f from, to;       // the wall's free end and the wall it runs to
  float thickness_px = 0.0f;  // the band's extent across the line (the wall's, plus a cell)
  // Filled by MeasureOpenings, per side of the line: the median free width parallel to it just
  // beside it (cells), and the median share of the line itself that is free within that width
  // (the rest is wall: the stub the opening continues, walls collinear with it, closed doors).
  float side_px[2] = {0.0f, 0.0f};
  float open_share[2] = {0.0f, 0.0f};
  // How open the line is against the space beside it: the smaller share of the two sides; 0
  // when a side is not free (a wall continued along another wall or the map's edge separates
  // nothing). About 1 where a wall's continuation crosses a corridor or any space no wider than
  // itself; a partition with a 2.3 m sliding door in a 3.5 m room leaves 0.66; a 1 m desk in
  // the middle of a 4 m room leaves 0.75.
  [[nodiscard]] double Constriction() const {
    if (side_px[0] <= 0.0f || side_px[1] <= 0.0f) return 0.0;
    return static_cast<double>(std::min(open_share[0], open_share[1]));
  }
};

// What made an opening (WallEvidence::opening_kinds holds these as bits; a cell where two
// cross has both).
enum OpeningKind : std::uint8_t {
  kOpeningFreeEnd = 1,  // a thin wall continued from its free end (to a facing end too)
  kOpeningCorner = 2,   // a thin wall continued past a corner or a T
  kOpeningMouth = 4,    // the line between aligned wall ends
  kOpeningFacade = 8,   // the facade across a protrusion's mouth
  kOpeningCap = 16,     // across a thin wall's free end, perpendicular to it
};
inline constexpr int kOpeningKindCount = 5;

struct WallEvidence {
  cv::Mat walls;          // CV_8UC1, 255 = occupied cell on a straight wall run
  cv::Mat doorways;       // CV_8UC1, 255 = non-occupied cell in a gap between two collinear runs
  cv::Mat openings;       // CV_8UC1, 255 = non-occupied cell on a wall run continued from its free
                          // end to the next wall run (candidate border, see declutter.h)
  cv::Mat opening_ids;    // CV_32SC1, k > 0 where `openings` is set: the cell lies on
                          // opening_lines[k - 1] (where two cross, one of them)
  cv::Mat opening_kinds;  // CV_8UC1, OpeningKind bits where `openings` is set, else 0
  std::vector<OpeningLine> opening_lines;
  double angle_rad = 0.0;
};

// What FindWalls looks for, in cells (SegmentOptions holds them in metres). 0 turns a step off.
struct WallCells {
  int min_length = 0;      // a wall run: a straight occupied run at least this long...
  int gap = 0;             // ...collinear pieces up to this far apart joined (dashed walls)
  int door = 0;            // doorways: gaps up to this wide between two collinear runs
  int opening = 0;         // openings: a run continued from a free end to the next wall this near
  int thickness = 0;       // ...a free end is where the wall is at most this thick across the run
  int stub = 0;            // stubs: shorter joined pieces this long bound doorways and openings
  int facade = 0;          // facade openings up to this wide (needs `free`)
  int mouth = 0;           // mouths between aligned wall ends up to this wide (needs `free`)
  int facing = 0;          // openings reach this far to the free end of a collinear run facing it
  int corner = 0;          // runs ending at a corner or a T continued this far (needs `free`)
  int cap = 0;             // end caps across free ends up to this long (needs `free`)
  int end_min_extent = 0;  // ends of walls whose occupied component (8-connected, a cell of
                           // slack) spans less than this along both axes start no opening,
                           // corner continuation, cap or mouth (0 = off)
};

// Wall evidence along `angle_rad` and `angle_rad` + pi/2: occupied cells on a straight run of
// at least `min_length` (collinear pieces up to `gap` apart joined), and the doorways: gaps of
// at most `door` between two collinear runs, i.e. the wall continued across a door. Runs are
// only continued along their own direction, never across a corridor.
// Openings: each run continued from a free end (where the wall is at most `thickness` thick
// across the run: not a corner, a T or the face of a block) along its own direction across at
// most `opening` cells to the first cell of a wall run of either direction (a run that meets no
// wall within that length is not continued), or across at most `facing` cells when that first
// wall cell is the free end of a collinear run facing it (one wall with a wide sliding door).
// Corner openings (`corner` > 0, needs `free`): a thin wall's run that ends at a corner or a T
// (not a block's face) with free space just beyond is continued the same way across at most
// `corner` cells: the wall's line extended into the space beyond the corner (the open side of a
// closet set into a room's corner lies on it).
// End caps (`cap` > 0, needs `free`): from a thin wall's free end, the line across the end,
// perpendicular to the wall, on either side, through free space to the first wall at most `cap`
// cells away (the front of a closet whose side wall ends where its door closes). Not at a door's
// jamb: where the wall's line goes on within two door widths (`door`), nothing is capped.
// Stubs (`stub` > 0, below `min_length`): a straight piece at least `stub` long (no gap
// closing) that is joined to a wall run (one 8-connected occupied component, a cell of slack;
// pieces and runs collinear across at most `door` count as joined) and, when `free` (CV_8UC1,
// 255 = free, same size) is given, has free space on both sides across at least half its length
// (beyond at most `thickness` occupied cells), counts as a run for doorways and openings (a wall
// between two doors), though not for `walls` (decluttering).
// Facade openings (`facade` > 0, needs `free`): the building's exterior wall continued across
// the mouth of a protrusion (a balcony or loggia behind a full-width slider, a bay): a gap of
// more than `gap` and at most `facade` cells between two collinear pieces of the facade
// (straight occupied pieces of at least `stub`, or `min_length` without stubs, with free space
// on one side and the outside, unknown cells connected to the grid's border, on the other),
// holding no occupied cell and none of the outside (a window or a notch is no mouth).
// Mouths (`mouth` > 0, needs `free`): the line between the aligned free ends of two parallel
// runs (a closet or wardrobe whose whole front is a door, a recess, a corridor's end), more
// than `gap` and at most `mouth` cells long, with nothing occupied and none of the outside on
// it.
// Facade openings and mouths are openings like the others: candidates that segmentation.h keeps
// or merges back.
// Small components (`end_min_extent` > 0): a run whose occupied component (8-connected after a
// one-cell dilation) spans fewer than `end_min_extent` cells along both axes of the rotated
// frame (a clutter block, a door leaf standing free, a loose piece of scan) starts none of the
// above from its ends; it is still a wall the others run to.
[[nodiscard]] WallEvidence FindWalls(const cv::Mat& occupied, double angle_rad,
                                     const WallCells& cells, const cv::Mat& free = cv::Mat());

// Measures every opening of `evidence` in `free` (CV_8UC1, 255 = free, same size). On each side,
// at every offset from just beyond its band to `side_depth_px`, opposite a quarter, the middle
// and three quarters of its length, the free run parallel to the line gives a width and an
// interval; the share of free cells on the line itself within that interval is the open share.
// Medians over those points are kept (OpeningLine); points that are not free are skipped, a
// side with none is 0.
// Rotated lines are walked in half-cell steps.
void MeasureOpenings(const cv::Mat& free, int side_depth_px, WallEvidence* evidence);

// Free space after decluttering (255 = free): `free` plus every non-free island (8-connected
// component of ~free not touching the border) that holds no cell of `walls`.
[[nodiscard]] cv::Mat FillClutterIslands(const cv::Mat& free, const cv::Mat& walls);

}  // namespace zm
