// Decluttering by dominant wall directions: the dominant angle of an axis-aligned map, runs of
// rotated walls,
// wall runs versus furniture, doorways only between collinear runs (never across a corridor),
// openings only from a thin wall's free end to the next wall within the opening width, and
// clutter islands filled unless they hold a wall or touch the border.
#include "zones/declutter.h"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

namespace zm {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A closed outline of a w x h rectangle rotated by `deg` around (cx, cy), 1 cell thick.
cv::Mat RotatedRoom(double deg, int w, int h) {
  cv::Mat occ = cv::Mat::zeros(300, 300, CV_8U);
  const cv::RotatedRect rect(cv::Point2f(150, 150), cv::Size2f(static_cast<float>(w),
                                                               static_cast<float>(h)),
                             static_cast<float>(deg));
  cv::Point2f p[4];
  rect.points(p);
  for (int i = 0; i < 4; ++i) cv::line(occ, p[i], p[(i + 1) % 4], cv::Scalar(255), 1);
  return occ;
}

TEST_CASE("the dominant wall angle of an axis-aligned map is 0") {
  // Rotated maps: one-cell-thin walls are staircases whose Sobel orientations lean towards the
  // axes, and the estimate was measured 0.6 to 12 degrees off for 20-65 degree rooms; that is a
  // known limitation (docs/segmentation.md), every evaluated map is axis-aligned.
  CHECK(std::abs(DominantWallAngle(RotatedRoom(0.0, 200, 120))) < 1.0 * kDeg);
  CHECK(std::abs(DominantWallAngle(RotatedRoom(90.0, 200, 120))) < 1.0 * kDeg);
  CHECK(DominantWallAngle(cv::Mat::zeros(50, 50, CV_8U)) == 0.0);
}

TEST_CASE("walls are long straight runs; doorways join collinear runs only") {
  // Two horizontal walls 2.0 m apart (a corridor, 40 cells), the upper one with a 0.9 m gap (a
  // door, 18 cells); a 0.4 m blob of furniture in the corridor, over 0.45 m from both walls.
  cv::Mat occ = cv::Mat::zeros(100, 200, CV_8U);
  cv::line(occ, {10, 40}, {90, 40}, cv::Scalar(255));
  cv::line(occ, {109, 40}, {190, 40}, cv::Scalar(255));
  cv::line(occ, {10, 80}, {190, 80}, cv::Scalar(255));
  cv::rectangle(occ, cv::Rect(140, 55, 8, 6), cv::Scalar(255), cv::FILLED);
  const WallEvidence w = FindWalls(occ, 0.0, /*min_length_px=*/20, /*gap_px=*/9,
                                   /*door_px=*/24);
  CHECK(w.walls.at<std::uint8_t>(40, 50) == 255);
  CHECK(w.walls.at<std::uint8_t>(80, 100) == 255);
  CHECK(w.walls.at<std::uint8_t>(57, 143) == 0);  // furniture is no wall
  CHECK(w.doorways.at<std::uint8_t>(40, 100) == 255);  // the door gap is closed...
  for (int r = 42; r < 79; ++r) {  // ...but nothing across the corridor between the two walls
    CHECK(w.doorways.at<std::uint8_t>(r, 100) == 0);
  }
  // A gap wider than a door stays open.
  const WallEvidence narrow = FindWalls(occ, 0.0, 20, 9, /*door_px=*/12);
  CHECK(narrow.doorways.at<std::uint8_t>(40, 100) == 0);
}

TEST_CASE("openings continue a thin wall from its free end to the next wall, nowhere else") {
  // A 6 x 4 m room (1 cell = 5 cm) with a 1.5 m partition from the top wall (free end at row
  // 60, 2.5 m above the bottom wall), a 0.6 m deep solid block against the bottom wall and a
  // 2.5 m partition from the left wall, lower down, ending 3.5 m short of the right wall.
  cv::Mat occ = cv::Mat::zeros(100, 140, CV_8U);
  cv::rectangle(occ, cv::Rect(10, 10, 121, 81), cv::Scalar(255), 2);
  cv::rectangle(occ, cv::Rect(69, 10, 2, 50), cv::Scalar(255), cv::FILLED);
  cv::rectangle(occ, cv::Rect(90, 78, 30, 12), cv::Scalar(255), cv::FILLED);
  cv::rectangle(occ, cv::Rect(10, 70, 50, 2), cv::Scalar(255), cv::FILLED);
  const WallEvidence w = FindWalls(occ, 0.0, /*min_length_px=*/20, /*gap_px=*/9,
                                   /*door_px=*/24, /*opening_px=*/60, /*thickness_px=*/6);
  // The partition's free end is continued down to the bottom wall: a 2.5 m opening.
  for (int r = 62; r < 88; ++r) CHECK(w.openings.at<std::uint8_t>(r, 70) == 255);
  // Its top end meets the top wall (a T): nothing is continued above it or beside it.
  CHECK(w.openings.at<std::uint8_t>(30, 75) == 0);
  // The left partition's end is 3.5 m (70 cells) from the right wall: beyond an opening.
  CHECK(w.openings.at<std::uint8_t>(71, 90) == 0);
  // The solid block's top face is no free end of its columns: no openings above it.
  CHECK(w.openings.at<std::uint8_t>(60, 100) == 0);
  // Without the opening width nothing is continued.
  const WallEvidence none = FindWalls(occ, 0.0, 20, 9, 24);
  CHECK(cv::countNonZero(none.openings) == 0);
}

TEST_CASE("walls rotated off the axes are found in the rotated frame") {
  const double deg = 25.0;
  const cv::Mat occ = RotatedRoom(deg, 200, 120);
  const WallEvidence w = FindWalls(occ, deg * kDeg, 20, 9, 0);
  CHECK(cv::countNonZero(w.walls) > 0.9 * cv::countNonZero(occ));
}

TEST_CASE("clutter islands become free unless they hold a wall or touch the border") {
  cv::Mat free = cv::Mat(100, 100, CV_8U, cv::Scalar(255));
  cv::rectangle(free, cv::Rect(0, 0, 100, 5), cv::Scalar(0), cv::FILLED);     // border wall
  cv::rectangle(free, cv::Rect(20, 20, 30, 20), cv::Scalar(0), cv::FILLED);   // furniture
  cv::rectangle(free, cv::Rect(60, 60, 30, 3), cv::Scalar(0), cv::FILLED);    // partition
  cv::Mat walls = cv::Mat::zeros(free.size(), CV_8U);
  walls.at<std::uint8_t>(61, 70) = 255;
  const cv::Mat out = FillClutterIslands(free, walls);
  CHECK(out.at<std::uint8_t>(30, 30) == 255);
  CHECK(out.at<std::uint8_t>(61, 80) == 0);
  CHECK(out.at<std::uint8_t>(2, 50) == 0);
}

}  // namespace
}  // namespace zm
