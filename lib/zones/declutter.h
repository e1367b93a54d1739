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

#include <opencv2/core/mat.hpp>

namespace zm {

// The dominant wall direction of `occupied` (CV_8UC1, 255 = occupied), in radians in
// [-pi/4, pi/4): walls run at this angle and at this angle + pi/2 (image x right, y down).
// 0 when there is no occupied boundary.
[[nodiscard]] double DominantWallAngle(const cv::Mat& occupied);

struct WallEvidence {
  cv::Mat walls;     // CV_8UC1, 255 = occupied cell on a straight wall run
  cv::Mat doorways;  // CV_8UC1, 255 = non-occupied cell in a gap between two collinear runs
  cv::Mat openings;  // CV_8UC1, 255 = non-occupied cell on a wall run continued from its free
                     // end to the next wall run (candidate border, see declutter.h)
  double angle_rad = 0.0;
};

// Wall evidence along `angle_rad` and `angle_rad` + pi/2: occupied cells on a straight run of
// at least `min_length_px` (collinear pieces up to `gap_px` apart joined), and the doorways:
// gaps of at most `door_px` between two collinear runs, i.e. the wall continued across a door
// (0 = none). Runs are only continued along their own direction, never across a corridor.
// Openings: each run continued from a free end (where the wall is at most `thickness_px` thick
// across the run: not a corner, a T or the face of a block) along its own direction across at
// most `opening_px` cells to the first cell of a wall run of either direction (0 = none; a run
// that meets no wall within that length is not continued).
[[nodiscard]] WallEvidence FindWalls(const cv::Mat& occupied, double angle_rad,
                                     int min_length_px, int gap_px, int door_px,
                                     int opening_px = 0, int thickness_px = 0);

// Free space after decluttering (255 = free): `free` plus every non-free island (8-connected
// component of ~free not touching the border) that holds no cell of `walls`.
[[nodiscard]] cv::Mat FillClutterIslands(const cv::Mat& free, const cv::Mat& walls);

}  // namespace zm
