// Decluttering by dominant wall directions: the dominant angle of an axis-aligned map, runs of
// rotated walls,
// wall runs versus furniture, doorways only between collinear runs (never across a corridor),
// openings only from a thin wall's free end to the next wall within the opening width, short
// wall pieces joined to a wall and seen from both sides bounding doors (furniture against a
// wall and free-standing pieces not), the facade continued across a balcony's mouth (not a
// window's or a notch's), the mouth between two aligned wall ends, a wall end reaching a
// collinear one facing it beyond an opening's width, a thin wall ending at a corner continued
// into the free space beyond it, a free end capped across (not a door's jamb), openings measured
// against the space beside them (each point as the definition walks it), and clutter islands filled
// unless they hold a wall or touch the border.
#include "segment/declutter.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace zm {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A closed outline of a w x h rectangle rotated by `deg` around (cx, cy), 1 cell thick.
cv::Mat RotatedRoom(double deg, int w, int h) {
  cv::Mat occ = cv::Mat::zeros(300, 300, CV_8U);
  const cv::RotatedRect rect(cv::Point2f(150, 150),
                             cv::Size2f(static_cast<float>(w), static_cast<float>(h)),
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

TEST_CASE("walls are long straight runs, doorways join collinear runs only") {
  // Two horizontal walls 2.0 m apart (a corridor, 40 cells), the upper one with a 0.9 m gap (a
  // door, 18 cells); a 0.4 m blob of furniture in the corridor, over 0.45 m from both walls.
  cv::Mat occ = cv::Mat::zeros(100, 200, CV_8U);
  cv::line(occ, {10, 40}, {90, 40}, cv::Scalar(255));
  cv::line(occ, {109, 40}, {190, 40}, cv::Scalar(255));
  cv::line(occ, {10, 80}, {190, 80}, cv::Scalar(255));
  cv::rectangle(occ, cv::Rect(140, 55, 8, 6), cv::Scalar(255), cv::FILLED);
  const WallEvidence w = FindWalls(occ, 0.0, {.min_length = 20, .gap = 9, .door = 24});
  CHECK(w.walls.at<std::uint8_t>(40, 50) == 255);
  CHECK(w.walls.at<std::uint8_t>(80, 100) == 255);
  CHECK(w.walls.at<std::uint8_t>(57, 143) == 0);       // furniture is no wall
  CHECK(w.doorways.at<std::uint8_t>(40, 100) == 255);  // the door gap is closed...
  for (int r = 42; r < 79; ++r) {  // ...but nothing across the corridor between the two walls
    CHECK(w.doorways.at<std::uint8_t>(r, 100) == 0);
  }
  // A gap wider than a door stays open.
  const WallEvidence narrow = FindWalls(occ, 0.0, {.min_length = 20, .gap = 9, .door = 12});
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
  const WallEvidence w =
      FindWalls(occ, 0.0, {.min_length = 20, .gap = 9, .door = 24, .opening = 60, .thickness = 6});
  // The partition's free end is continued down to the bottom wall: a 2.5 m opening.
  for (int r = 62; r < 88; ++r) CHECK(w.openings.at<std::uint8_t>(r, 70) == 255);
  // Its top end meets the top wall (a T): nothing is continued above it or beside it.
  CHECK(w.openings.at<std::uint8_t>(30, 75) == 0);
  // The left partition's end is 3.5 m (70 cells) from the right wall: beyond an opening.
  CHECK(w.openings.at<std::uint8_t>(71, 90) == 0);
  // The solid block's top face is no free end of its columns: no openings above it.
  CHECK(w.openings.at<std::uint8_t>(60, 100) == 0);
  // Without the opening width nothing is continued.
  const WallEvidence none = FindWalls(occ, 0.0, {.min_length = 20, .gap = 9, .door = 24});
  CHECK(cv::countNonZero(none.openings) == 0);
}

TEST_CASE("a short wall piece joined to a wall and seen from both rooms bounds a door") {
  // A 6 x 4 m room (1 cell = 5 cm) crossed at row 50 by a wall: a 0.8 m piece from the left
  // wall, a 0.9 m door, a 0.6 m piece standing free, a 0.9 m door, then a long wall to the right
  // wall. The pieces are shorter than a wall run (1 m, 20 cells).
  cv::Mat occ = cv::Mat::zeros(100, 140, CV_8U);
  cv::rectangle(occ, cv::Rect(10, 10, 121, 81), cv::Scalar(255), 2);
  cv::line(occ, {10, 50}, {26, 50}, cv::Scalar(255));   // joined to the left wall
  cv::line(occ, {45, 50}, {56, 50}, cv::Scalar(255));   // between the two doors
  cv::line(occ, {75, 50}, {130, 50}, cv::Scalar(255));  // a wall run
  cv::Mat free = cv::Mat::zeros(occ.size(), CV_8U);
  free(cv::Rect(12, 12, 117, 77)).setTo(255);
  free.setTo(0, occ);
  auto walls = [&](int stub_px, const cv::Mat& f) {
    return FindWalls(occ, 0.0,
                     {.min_length = 20, .gap = 9, .door = 24, .thickness = 6, .stub = stub_px}, f);
  };
  const WallEvidence w = walls(/*stub_px=*/6, free);
  CHECK(w.doorways.at<std::uint8_t>(50, 35) == 255);  // both doors are closed
  CHECK(w.doorways.at<std::uint8_t>(50, 65) == 255);
  CHECK(w.walls.at<std::uint8_t>(50, 20) == 0);  // a stub is no wall run for decluttering
  // Without stubs only the wall run is a run: neither gap is a door.
  const WallEvidence off = walls(0, free);
  CHECK(off.doorways.at<std::uint8_t>(50, 35) == 0);
  CHECK(off.doorways.at<std::uint8_t>(50, 65) == 0);
  // The same piece with unknown cells below it (furniture against the wall, its inside or
  // shadow unseen) is no stub; the middle piece then joins nothing but the run on its right.
  cv::Mat shadow = free.clone();
  shadow(cv::Rect(12, 51, 15, 10)).setTo(0);
  const WallEvidence clutter = walls(6, shadow);
  CHECK(clutter.doorways.at<std::uint8_t>(50, 35) == 0);
  CHECK(clutter.doorways.at<std::uint8_t>(50, 65) == 255);
  // A piece standing free with no wall within a door's width of it is no stub either.
  cv::Mat lone = cv::Mat::zeros(occ.size(), CV_8U);
  cv::rectangle(lone, cv::Rect(10, 10, 121, 81), cv::Scalar(255), 2);
  cv::line(lone, {60, 50}, {72, 50}, cv::Scalar(255));
  cv::line(lone, {60, 70}, {72, 70}, cv::Scalar(255));
  const WallEvidence alone = FindWalls(
      lone, 0.0, {.min_length = 20, .gap = 9, .door = 24, .thickness = 6, .stub = 6}, free);
  CHECK(cv::countNonZero(alone.doorways(cv::Rect(30, 40, 80, 40))) == 0);
}

// Free (255) inside the building's outline `inside`, minus the occupied cells; unknown elsewhere
// (the outside).
cv::Mat FreeInside(const cv::Mat& occ, const std::vector<cv::Rect>& inside) {
  cv::Mat free = cv::Mat::zeros(occ.size(), CV_8U);
  for (const cv::Rect& r : inside) free(r).setTo(255);
  free.setTo(0, occ);
  return free;
}

// A 6 x 4 m room (1 cell = 5 cm, walls 2 cells thick: columns 10-130, rows 10-90) with these
// wall rectangles filled in, and its free inside.
struct Room {
  cv::Mat occ = cv::Mat::zeros(100, 140, CV_8U);
  explicit Room(const std::vector<cv::Rect>& walls) {
    cv::rectangle(occ, cv::Rect(10, 10, 121, 81), cv::Scalar(255), 2);
    for (const cv::Rect& w : walls) occ(w).setTo(255);
  }
  [[nodiscard]] cv::Mat Free() const { return FreeInside(occ, {cv::Rect(12, 12, 117, 77)}); }
};

TEST_CASE("the facade is continued across a balcony's mouth, not across a window or a notch") {
  // A 6 x 4 m flat (1 cell = 5 cm, walls 3 cells thick) with a 2 m x 1 m balcony protruding
  // below its bottom wall behind a full-width slider: the bottom wall is two facade pieces, the
  // balcony's mouth (columns 50-89) lies between them. Its top wall has a 1 m window onto the
  // outside; its right wall a 2 m notch of the outside (an inset entrance).
  cv::Mat occ = cv::Mat::zeros(140, 160, CV_8U);
  auto wall = [&](int x, int y, int w, int h) {
    cv::rectangle(occ, cv::Rect(x, y, w, h), cv::Scalar(255), cv::FILLED);
  };
  wall(10, 10, 121, 3);  // top, a window at columns 60-79
  occ(cv::Rect(60, 10, 20, 3)).setTo(0);
  wall(10, 10, 3, 83);   // left
  wall(128, 10, 3, 30);  // right, above the notch
  wall(128, 70, 3, 23);  // right, below the notch
  wall(108, 37, 23, 3);  // the notch's top...
  wall(108, 37, 3, 36);  // ...back...
  wall(108, 70, 23, 3);  // ...and bottom
  wall(10, 90, 40, 3);   // bottom, left of the balcony
  wall(90, 90, 41, 3);   // bottom, right of it
  wall(47, 90, 3, 23);   // the balcony's sides and front
  wall(90, 90, 3, 23);
  wall(47, 110, 46, 3);
  cv::Mat free = FreeInside(occ, {cv::Rect(13, 13, 115, 77), cv::Rect(50, 90, 40, 20)});
  free(cv::Rect(108, 40, 23, 30)).setTo(0);  // the notch is outside
  const WallCells cells{
      .min_length = 20, .gap = 9, .door = 24, .thickness = 6, .stub = 6, .facade = 60};
  const WallEvidence w = FindWalls(occ, 0.0, cells, free);
  for (int c = 52; c < 88; ++c) CHECK(w.openings.at<std::uint8_t>(91, c) == 255);
  CHECK(cv::countNonZero(w.openings(cv::Rect(58, 5, 24, 12))) == 0);    // not the window
  CHECK(cv::countNonZero(w.openings(cv::Rect(120, 40, 15, 30))) == 0);  // not the notch
  REQUIRE(!w.opening_lines.empty());
  // Off, or without the free space to tell the outside from a room, nothing is found.
  WallCells off = cells;
  off.facade = 0;
  CHECK(cv::countNonZero(FindWalls(occ, 0.0, off, free).openings) == 0);
  CHECK(cv::countNonZero(FindWalls(occ, 0.0, cells).openings) == 0);
}

TEST_CASE("the mouth between two aligned wall ends is an opening, something in it is not") {
  // A 6 x 4 m room (1 cell = 5 cm) with a wardrobe against its top wall: two 0.75 m side
  // walls (15 cells, 0.1 m thick) 1.6 m apart whose free ends are aligned at row 27, the front
  // being one wide door. Further right two more walls from the top wall end 0.5 m apart in
  // height: not aligned, no mouth.
  const Room room({{30, 10, 2, 18}, {62, 10, 2, 18}, {90, 10, 2, 18}, {115, 10, 2, 28}});
  const cv::Mat& occ = room.occ;
  const cv::Mat free = room.Free();
  const WallCells cells{
      .min_length = 20, .gap = 9, .door = 24, .thickness = 6, .stub = 6, .mouth = 60};
  const WallEvidence w = FindWalls(occ, 0.0, cells, free);
  for (int c = 34; c < 60; ++c) CHECK(w.openings.at<std::uint8_t>(27, c) == 255);
  CHECK(cv::countNonZero(w.openings(cv::Rect(93, 12, 21, 30))) == 0);
  // A box standing in the mouth: nothing.
  cv::Mat blocked = occ.clone();
  cv::rectangle(blocked, cv::Rect(44, 24, 4, 6), cv::Scalar(255), cv::FILLED);
  const WallEvidence b =
      FindWalls(blocked, 0.0, cells, FreeInside(blocked, {cv::Rect(12, 12, 117, 77)}));
  CHECK(cv::countNonZero(b.openings(cv::Rect(33, 25, 28, 4))) == 0);
}

TEST_CASE("beyond an opening's width a wall end reaches only a collinear wall end facing it") {
  // A 10 x 4 m room (1 cell = 5 cm) split by one wall with a 3.5 m sliding door: two thin pieces
  // from the side walls along row 50, their free ends 70 cells apart. Below, a thin wall from
  // the left wall ends 3.5 m short of the right wall: nothing faces it.
  cv::Mat occ = cv::Mat::zeros(100, 220, CV_8U);
  cv::rectangle(occ, cv::Rect(10, 10, 201, 81), cv::Scalar(255), 2);
  cv::rectangle(occ, cv::Rect(10, 50, 60, 2), cv::Scalar(255), cv::FILLED);
  cv::rectangle(occ, cv::Rect(140, 50, 71, 2), cv::Scalar(255), cv::FILLED);
  cv::rectangle(occ, cv::Rect(10, 75, 130, 2), cv::Scalar(255), cv::FILLED);
  const WallCells cells{
      .min_length = 20, .gap = 9, .door = 24, .opening = 60, .thickness = 6, .facing = 80};
  const WallEvidence w = FindWalls(occ, 0.0, cells);
  for (int c = 72; c < 138; ++c) CHECK(w.openings.at<std::uint8_t>(50, c) == 255);
  CHECK(w.openings.at<std::uint8_t>(76, 175) == 0);
  // With the facing reach off the 3.5 m gap is beyond an opening.
  WallCells off = cells;
  off.facing = 0;
  CHECK(FindWalls(occ, 0.0, off).openings.at<std::uint8_t>(50, 105) == 0);
}

TEST_CASE("a thin wall ending at a corner is continued into the free space beyond it") {
  // A 6 x 4 m room (1 cell = 5 cm) with a 1.5 x 1.5 m closet set against its top wall (side
  // walls at columns 50 and 80, front wall at rows 40-41, 0.1 m thick) and a solid 1.5 x 0.6 m
  // block against the bottom wall.
  const Room room({{50, 10, 2, 32}, {80, 10, 2, 32}, {50, 40, 32, 2}, {90, 78, 30, 12}});
  const cv::Mat& occ = room.occ;
  const cv::Mat free = room.Free();
  const WallCells cells{.min_length = 20, .gap = 9, .door = 24, .thickness = 6, .corner = 60};
  const WallEvidence w = FindWalls(occ, 0.0, cells, free);
  // The closet's side walls end at its front wall's corners: continued down to the bottom wall;
  // its front wall is continued left and right to the room's side walls.
  for (int r = 43; r < 77; ++r) {
    CHECK(w.openings.at<std::uint8_t>(r, 51) == 255);
    CHECK(w.opening_kinds.at<std::uint8_t>(r, 51) == kOpeningCorner);
  }
  for (int c = 12; c < 49; ++c) CHECK(w.openings.at<std::uint8_t>(41, c) == 255);
  for (int c = 83; c < 129; ++c) CHECK(w.openings.at<std::uint8_t>(40, c) == 255);
  // The block's faces and the room's outline (the outside beyond its corners) are not.
  CHECK(cv::countNonZero(w.openings(cv::Rect(83, 78, 6, 11))) == 0);
  CHECK(cv::countNonZero(w.openings(cv::Rect(90, 50, 30, 27))) == 0);
  CHECK(cv::countNonZero(w.openings(cv::Rect(12, 50, 30, 38))) == 0);
  // Off by default, and without the free space.
  WallCells off = cells;
  off.corner = 0;
  CHECK(cv::countNonZero(FindWalls(occ, 0.0, off, free).openings) == 0);
  CHECK(cv::countNonZero(FindWalls(occ, 0.0, cells).openings) == 0);
}

TEST_CASE("a thin wall's free end is capped across, to the next wall, a door's jambs are not") {
  // A 6 x 4 m room (1 cell = 5 cm) with a 1.5 m partition down from the top wall (column 60,
  // free end at row 40): the wall on its left is 2.4 m away, the one on its right 3.3 m.
  const Room room({{60, 10, 2, 31}});
  const cv::Mat& occ = room.occ;
  const cv::Mat free = room.Free();
  const WallCells cells{.min_length = 20, .gap = 9, .door = 24, .thickness = 6, .cap = 60};
  const WallEvidence w = FindWalls(occ, 0.0, cells, free);
  for (int c = 12; c < 60; ++c) {
    CHECK(w.openings.at<std::uint8_t>(40, c) == 255);
    CHECK(w.opening_kinds.at<std::uint8_t>(40, c) == kOpeningCap);
  }
  CHECK(cv::countNonZero(w.openings(cv::Rect(62, 12, 67, 77))) == 0);
  // The partition is not continued (no opening width) and the outline's corners are no ends.
  CHECK(cv::countNonZero(w.openings(cv::Rect(12, 42, 117, 47))) == 0);
  CHECK(cv::countNonZero(w.openings(cv::Rect(12, 12, 47, 27))) == 0);
  // A wall with a 1 m door: its ends are the door's jambs, the wall goes on beyond the gap, and
  // nothing is capped there (a cap would cut the room at every door).
  const Room door({{60, 10, 2, 31}, {12, 70, 68, 2}, {100, 70, 29, 2}});
  const WallEvidence d = FindWalls(door.occ, 0.0, cells, door.Free());
  CHECK(cv::countNonZero(d.openings(cv::Rect(76, 42, 28, 27))) == 0);
  CHECK(cv::countNonZero(d.openings(cv::Rect(76, 73, 28, 15))) == 0);
  // Off by default.
  WallCells off = cells;
  off.cap = 0;
  CHECK(cv::countNonZero(FindWalls(occ, 0.0, off, free).openings) == 0);
}

TEST_CASE("the ends of a small free-standing piece start no opening or cap when asked") {
  // A 6 x 4 m room (1 cell = 5 cm) with a 1.5 m partition down from the top wall (column 100,
  // free end at row 40) and a free-standing 1.2 m bar (a bench, a loose door leaf: columns
  // 30-53, rows 65-66) that touches nothing.
  const Room room({{100, 10, 2, 31}, {30, 65, 24, 2}});
  const cv::Mat& occ = room.occ;
  const cv::Mat free = room.Free();
  const WallCells cells{
      .min_length = 20, .gap = 9, .door = 24, .opening = 60, .thickness = 6, .cap = 60};
  const WallEvidence w = FindWalls(occ, 0.0, cells, free);
  // Off (the default): the bar is continued to the left wall and capped up and down.
  CHECK(w.openings.at<std::uint8_t>(65, 20) == 255);
  CHECK(cv::countNonZero(w.openings(cv::Rect(30, 70, 1, 15))) > 0);
  CHECK(w.openings.at<std::uint8_t>(40, 115) == 255);  // the partition's cap
  // On, the bar's ends (its component spans less than 1.5 m) start nothing; the partition,
  // joined to the room's outline, is capped and continued as before.
  WallCells small = cells;
  small.end_min_extent = 30;
  const WallEvidence s = FindWalls(occ, 0.0, small, free);
  CHECK(cv::countNonZero(s.openings(cv::Rect(12, 60, 20, 10))) == 0);
  CHECK(cv::countNonZero(s.openings(cv::Rect(26, 12, 32, 50))) == 0);
  CHECK(cv::countNonZero(s.openings(cv::Rect(26, 69, 32, 19))) == 0);
  CHECK(s.openings.at<std::uint8_t>(40, 115) == 255);
  CHECK(s.openings.at<std::uint8_t>(60, 100) == 255);
}

TEST_CASE("an opening across a corridor is open, a partition's opening constricts the room") {
  // MeasureOpenings on hand-made lines (1 cell = 5 cm). A corridor 1.6 m wide crossed by an
  // opening from wall to wall: the space beside the line is as wide as the line is open.
  cv::Mat corridor = cv::Mat::zeros(100, 140, CV_8U);
  corridor(cv::Rect(10, 40, 120, 32)).setTo(255);
  WallEvidence across;
  OpeningLine line;
  line.from = {70.0f, 40.0f};
  line.to = {70.0f, 71.0f};
  line.thickness_px = 3.0f;
  across.opening_lines = {line};
  MeasureOpenings(corridor, /*side_depth_px=*/20, &across);
  CHECK(across.opening_lines[0].Constriction() > 0.9);
  // A 4 m deep room with a 1.5 m partition from its top wall: the opening below it is 2.5 m of
  // the 4 m beside it.
  cv::Mat room = cv::Mat::zeros(100, 140, CV_8U);
  room(cv::Rect(10, 10, 120, 80)).setTo(255);
  room(cv::Rect(69, 10, 3, 30)).setTo(0);
  WallEvidence partition;
  line.from = {70.0f, 40.0f};
  line.to = {70.0f, 89.0f};
  partition.opening_lines = {line};
  MeasureOpenings(room, 20, &partition);
  const double c = partition.opening_lines[0].Constriction();
  CHECK(c > 0.55);
  CHECK(c < 0.7);
  // A line with no free space on one side (a wall continued along the map's edge) separates
  // nothing: 0.
  cv::Mat edge = cv::Mat::zeros(100, 140, CV_8U);
  edge(cv::Rect(72, 10, 58, 80)).setTo(255);
  WallEvidence along;
  along.opening_lines = {line};
  MeasureOpenings(edge, 20, &along);
  CHECK(along.opening_lines[0].Constriction() == 0.0);
}

// MeasureOpenings' definition (declutter.h), walked point by point: at each offset beside the
// line, opposite a quarter, the middle and three quarters of it, the free run parallel to the
// line in half-cell steps (cells rounded halves away from zero), and the share of the line's
// half-steps over that run that are free; medians per side.
namespace {
void MeasureOpeningsByDefinition(const cv::Mat& free, int side_depth_px, OpeningLine* line) {
  auto is_free = [&](cv::Point2f q) {
    const int c = static_cast<int>(std::lround(q.x)), r = static_cast<int>(std::lround(q.y));
    return r >= 0 && c >= 0 && r < free.rows && c < free.cols && free.at<std::uint8_t>(r, c) != 0;
  };
  auto reach = [&](cv::Point2f p, cv::Point2f dir) {
    if (!is_free(p)) return -1.0f;
    float t = 0.5f;
    while (is_free(p + t * dir)) t += 0.5f;
    return t - 0.5f;
  };
  auto median = [](std::vector<float> v) {
    if (v.empty()) return 0.0f;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const cv::Point2f d = line->to - line->from;
  const float len = std::hypot(d.x, d.y);
  const cv::Point2f dir = len > 0.0f ? d * (1.0f / len) : cv::Point2f(1.0f, 0.0f);
  const cv::Point2f normal(-dir.y, dir.x);
  const int first = static_cast<int>(std::ceil(0.5f * line->thickness_px)) + 1;
  for (int side = 0; side < 2; ++side) {
    std::vector<float> widths, shares;
    for (const float u : {0.25f, 0.5f, 0.75f}) {
      const cv::Point2f on_line = line->from + u * d;
      for (int k = first; k <= std::max(first, side_depth_px); ++k) {
        const cv::Point2f p = on_line + (side == 0 ? -1.0f : 1.0f) * static_cast<float>(k) * normal;
        const float ahead = reach(p, dir);
        if (ahead < 0.0f) continue;
        const float behind = reach(p, -dir);
        widths.push_back(ahead + behind + 1.0f);
        int open = 0, all = 0;
        for (float t = -behind; t <= ahead; t += 0.5f, ++all) open += is_free(on_line + t * dir);
        shares.push_back(static_cast<float>(open) / static_cast<float>(std::max(1, all)));
      }
    }
    line->side_px[side] = median(widths);
    line->open_share[side] = median(shares);
  }
}

}  // namespace

TEST_CASE("MeasureOpenings measures every line as its definition does, rotated lines too") {
  // Random rooms, clutter and lines (axis-aligned, at half cells where rounding ties, rotated,
  // and running off the grid): each side's width and open share equal the definition's
  // exactly (MeasureOpenings counts each half-step of the line once and rounds inline).
  cv::RNG rng(28);
  for (int trial = 0; trial < 20; ++trial) {
    cv::Mat free = cv::Mat::zeros(120, 160, CV_8U);
    for (int i = 0; i < 6; ++i) {
      const int x = rng.uniform(0, 140), y = rng.uniform(0, 100);
      free(cv::Rect(x, y, rng.uniform(5, 160 - x), rng.uniform(5, 120 - y))).setTo(255);
    }
    for (int i = 0; i < 40; ++i) {
      cv::circle(free, cv::Point(rng.uniform(0, 160), rng.uniform(0, 120)), rng.uniform(0, 4),
                 cv::Scalar(0), cv::FILLED);
    }
    WallEvidence measured;
    for (int i = 0; i < 12; ++i) {
      OpeningLine line;
      line.from = {rng.uniform(-5.0f, 165.0f), rng.uniform(-5.0f, 125.0f)};
      if (i % 3 == 0) line.from = {std::round(line.from.x) + 0.5f, std::round(line.from.y)};
      const float angle = i % 2 == 0 ? 0.0f : rng.uniform(0.0f, 6.3f);
      const float length = rng.uniform(0.0f, 80.0f);
      line.to = line.from + length * cv::Point2f(std::cos(angle), std::sin(angle));
      line.thickness_px = static_cast<float>(rng.uniform(1, 6));
      measured.opening_lines.push_back(line);
    }
    std::vector<OpeningLine> expected = measured.opening_lines;
    MeasureOpenings(free, 20, &measured);
    for (std::size_t i = 0; i < expected.size(); ++i) {
      MeasureOpeningsByDefinition(free, 20, &expected[i]);
      for (int side = 0; side < 2; ++side) {
        CHECK(measured.opening_lines[i].side_px[side] == expected[i].side_px[side]);
        CHECK(measured.opening_lines[i].open_share[side] == expected[i].open_share[side]);
      }
    }
  }
}

TEST_CASE("walls rotated off the axes are found in the rotated frame") {
  const double deg = 25.0;
  const cv::Mat occ = RotatedRoom(deg, 200, 120);
  const WallEvidence w = FindWalls(occ, deg * kDeg, {.min_length = 20, .gap = 9});
  CHECK(cv::countNonZero(w.walls) > 0.9 * cv::countNonZero(occ));
}

TEST_CASE("clutter islands become free unless they hold a wall or touch the border") {
  cv::Mat free = cv::Mat(100, 100, CV_8U, cv::Scalar(255));
  cv::rectangle(free, cv::Rect(0, 0, 100, 5), cv::Scalar(0), cv::FILLED);    // border wall
  cv::rectangle(free, cv::Rect(20, 20, 30, 20), cv::Scalar(0), cv::FILLED);  // furniture
  cv::rectangle(free, cv::Rect(60, 60, 30, 3), cv::Scalar(0), cv::FILLED);   // partition
  cv::Mat walls = cv::Mat::zeros(free.size(), CV_8U);
  walls.at<std::uint8_t>(61, 70) = 255;
  const cv::Mat out = FillClutterIslands(free, walls);
  CHECK(out.at<std::uint8_t>(30, 30) == 255);
  CHECK(out.at<std::uint8_t>(61, 80) == 0);
  CHECK(out.at<std::uint8_t>(2, 50) == 0);
}

}  // namespace
}  // namespace zm
