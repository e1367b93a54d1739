// Automatic zones: with the rule merges, a synthetic floor of rectangular rooms joined by doors
// is segmented exactly, also cluttered (furniture, unseen floor); unknown cells inside a room do
// not split it; a corridor with aligned rooms on both sides stays one corridor; each layout rule
// makes its room; with the default (the learned layout merge), the same floors; a real map stays
// above a labelled regression floor with each; grid loaders (YAML, PNG,
// RTAB-Map opt_map) place cells right and reject bad input with one clear error; keyframe-only
// zones and oversize splits respect their keyframe cap; an oracle trace is not bound by the
// model's cut options.
#include "segment/segmentation.h"

#include <doctest/doctest.h>
#include <sqlite3.h>
#include <zlib.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "segment/grid_map.h"
#include "segment/merge.h"
#include "segment/score.h"
#include "segment/split.h"
#include "segment/write.h"
#include "zones/polygon.h"
#include "zones/zone_set.h"

namespace zm {
namespace {

// The rule merges (issue 16, parts 1-4), which the tests below pin down one by one; the default
// (the learned layout merge) is tested on the same floors further down.
SegmentOptions Rules() {
  SegmentOptions o;
  o.learned.layout_merge_threshold = 0.0;
  return o;
}

std::filesystem::path TempDir(const std::string& name) {
  auto dir = std::filesystem::path(ZM_BINARY_DIR) / "segmentation_test" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A 0.05 m/px floor: a 12 x 1.6 m corridor along the top, three rooms below it (4 x 4, 4 x 4,
// 3.5 x 4 m), 0.1 m walls, a 0.9 m door from each room to the corridor. `truth` gets one label
// per room (1..3) and the corridor (4).
OccupancyGrid SyntheticFloor(cv::Mat* truth) {
  constexpr int kPx = 20;  // cells per metre
  OccupancyGrid grid;
  grid.resolution_m = 0.05;
  grid.cells = cv::Mat(8 * kPx, 14 * kPx, CV_8UC1, cv::Scalar(kCellUnknown));
  *truth = cv::Mat::zeros(grid.cells.size(), CV_32S);
  auto rect = [&](double x0, double y0, double x1, double y1) {
    return cv::Rect(cv::Point(static_cast<int>(x0 * kPx), static_cast<int>(y0 * kPx)),
                    cv::Point(static_cast<int>(x1 * kPx), static_cast<int>(y1 * kPx)));
  };
  // Outer wall block then free interiors (walls are what is left between them).
  cv::rectangle(grid.cells, rect(0.9, 0.9, 13.1, 7.1), cv::Scalar(kCellOccupied), cv::FILLED);
  const cv::Rect corridor = rect(1.0, 1.0, 13.0, 2.6);
  const cv::Rect rooms[3] = {rect(1.0, 2.7, 5.0, 7.0), rect(5.1, 2.7, 9.1, 7.0),
                             rect(9.2, 2.7, 13.0, 7.0)};
  cv::rectangle(grid.cells, corridor, cv::Scalar(kCellFree), cv::FILLED);
  cv::rectangle(*truth, corridor, cv::Scalar(4), cv::FILLED);
  for (int i = 0; i < 3; ++i) {
    cv::rectangle(grid.cells, rooms[i], cv::Scalar(kCellFree), cv::FILLED);
    cv::rectangle(*truth, rooms[i], cv::Scalar(i + 1), cv::FILLED);
    const double door_x = 2.0 + 4.1 * i;
    cv::rectangle(grid.cells, rect(door_x, 2.6, door_x + 0.9, 2.7), cv::Scalar(kCellFree),
                  cv::FILLED);
  }
  return grid;
}

TEST_CASE("a synthetic floor of rooms joined by doors is segmented one segment per room") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  auto seg = SegmentRooms(grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 4);
  auto score = ScoreSegmentation(seg->labels, truth);
  REQUIRE(score.ok());
  CHECK(score->gt_rooms == 4);
  CHECK(score->predicted_segments == 4);
  CHECK(score->precision > 0.99);
  CHECK(score->recall > 0.99);
  CHECK(score->mean_iou > 0.98);
  // The corridor is labelled by its shape, the rooms too.
  int corridors = 0;
  for (const auto& s : seg->segments) corridors += s.kind == "corridor" ? 1 : 0;
  CHECK(corridors == 1);

  // Polygons in metres, y up: the corridor (top rows of the image) has the largest y.
  auto zones = SegmentationToZones(*seg, grid);
  REQUIRE(zones.ok());
  REQUIRE(zones->size() == 4);
  for (const Zone& z : *zones) {
    CHECK(z.polygon.size() >= 4);
    CHECK(SignedArea(z.polygon) > 0.0);
    CHECK_FALSE(FindSelfIntersection(z.polygon).has_value());
    if (z.kind == "corridor") {
      // Corridor spans image rows 20..51 -> y from 8 - 2.6 = 5.4 m to 8 - 1.0 = 7.0 m.
      CHECK(PointInPolygon(z.polygon, {7.0, 6.2}));
      // Outlines run through the boundary cells' centres (half a cell inside) and are simplified.
      CHECK(SignedArea(z.polygon) > 0.88 * 12.0 * 1.6);
      CHECK(SignedArea(z.polygon) < 12.0 * 1.6 + 0.2);
    }
  }
  // The GeoJSON is accepted by the zones module's own loader.
  const auto dir = TempDir("synthetic");
  const std::string path = (dir / "zones.geojson").string();
  REQUIRE(WriteZonesGeoJson(*zones, path).ok());
  auto loaded = LoadZoneFile(path);
  REQUIRE_MESSAGE(loaded.ok(), loaded.status().ToString());
  CHECK(loaded->size() == 4);
  // Written by the zones module's one writer: floor 0's z range, explicit.
  CHECK(loaded->zones()[0].z_min_m == -0.5 * kDefaultFloorHeightM);
  CHECK(loaded->zones()[0].z_max_m == 0.5 * kDefaultFloorHeightM);
  // Through a stringstream: GCC 12 -O3 on aarch64 sees a null streambuf in the
  // istreambuf_iterator idiom (-Wnull-dereference, a false positive; tests/api/map_loop_test.cc).
  std::ifstream in(path);
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  CHECK(text.find("\"z_min\": -1.5") != std::string::npos);
}

// A floor drawn from rectangles at 0.05 m/px: everything unknown, an occupied block, free
// rectangles (rooms, corridor, doors) cut out of it. `truth` labels each room rectangle.
struct Floor {
  OccupancyGrid grid;
  cv::Mat truth;
  static constexpr int kPx = 20;  // cells per metre
  Floor(double w_m, double h_m) {
    grid.resolution_m = 0.05;
    grid.cells = cv::Mat(static_cast<int>(h_m * kPx), static_cast<int>(w_m * kPx), CV_8UC1,
                         cv::Scalar(kCellUnknown));
    truth = cv::Mat::zeros(grid.cells.size(), CV_32S);
    Fill(0.9, 0.9, w_m - 0.9, h_m - 0.9, kCellOccupied);
  }
  static cv::Rect R(double x0, double y0, double x1, double y1) {
    return {cv::Point(static_cast<int>(x0 * kPx), static_cast<int>(y0 * kPx)),
            cv::Point(static_cast<int>(x1 * kPx), static_cast<int>(y1 * kPx))};
  }
  void Fill(double x0, double y0, double x1, double y1, std::uint8_t v) {
    cv::rectangle(grid.cells, R(x0, y0, x1, y1), cv::Scalar(v), cv::FILLED);
  }
  void Room(double x0, double y0, double x1, double y1, int label) {
    Fill(x0, y0, x1, y1, kCellFree);
    cv::rectangle(truth, R(x0, y0, x1, y1), cv::Scalar(label), cv::FILLED);
  }
};

// A 20 x 1.6 m corridor (truth 100); five 4 m rooms above and five below (1-5, 11-15), their
// walls aligned across the corridor (1.6 m apart: wider than any door taken as one), each with a
// 0.9 m door.
Floor CorridorFloor() {
  Floor f(22.0, 12.0);
  f.Room(1.0, 5.2, 21.0, 6.8, 100);
  for (int i = 0; i < 5; ++i) {
    const double x0 = 1.0 + 4.0 * i;
    f.Room(x0, 1.0, x0 + 3.9, 5.1, i + 1);
    f.Room(x0, 6.9, x0 + 3.9, 11.0, i + 11);
    f.Fill(x0 + 1.5, 5.1, x0 + 2.4, 5.2, kCellFree);
    f.Fill(x0 + 1.5, 6.8, x0 + 2.4, 6.9, kCellFree);
  }
  return f;
}

// A 4 x 3 m room (1) with a 1.5 x 0.7 m wardrobe (2) against its top wall: two 0.7 m side
// walls (stubs) whose free ends are aligned, nothing between them.
Floor WardrobeFloor() {
  Floor f(6.0, 5.0);
  f.Room(1.0, 1.0, 5.0, 4.0, 1);
  f.Fill(2.0, 1.0, 2.1, 1.7, kCellOccupied);
  f.Fill(3.6, 1.0, 3.7, 1.7, kCellOccupied);
  cv::rectangle(f.truth, Floor::R(2.1, 1.0, 3.6, 1.7), cv::Scalar(2), cv::FILLED);
  return f;
}

// A model that merges nothing (p = sigmoid(-20)), recorded as trained with `o`: the layout pieces.
LayoutMergeModel NeverMerges(const SegmentOptions& o) {
  std::string names = "[";
  for (std::size_t i = 0; i < kLayoutFeatureNames.size(); ++i) {
    names += std::string(i ? "," : "") + "\"" + kLayoutFeatureNames[i] + "\"";
  }
  auto m = ParseLayoutMergeModel("{\"features\":" + names +
                                 "],\"init\":-20,\"learning_rate\":1,\"trees\":[],"
                                 "\"trained_with\":" +
                                 LayoutMergeTrainedWithJson(o.cut, o.rules) + "}");
  REQUIRE_MESSAGE(m.ok(), m.status().ToString());
  return std::move(m).value();
}

// An L-shaped room (1; its reflex corner's walls continue across it to the outer walls) and a
// 5 x 4 m room (2) with a 2 m long, 0.6 m deep cabinet against one wall and a 1.2 m desk against
// another: their fronts are straight runs whose continuations cut nothing for good.
Floor LShapedFloor() {
  Floor f(13.0, 8.0);
  f.Room(1.0, 1.0, 4.0, 7.0, 1);  // the L: a 3 x 6 m arm...
  f.Room(1.0, 4.0, 7.0, 7.0, 1);  // ...and a 6 x 3 m arm
  f.Room(7.1, 1.0, 12.0, 5.0, 2);
  f.Fill(7.0, 4.05, 7.1, 4.95, kCellFree);      // a 0.9 m door from the L's arm to the room
  f.Fill(8.0, 1.0, 10.0, 1.6, kCellOccupied);   // cabinet against the top wall
  f.Fill(11.4, 2.5, 12.0, 3.7, kCellOccupied);  // desk against the right wall
  return f;
}

int CountKind(const Segmentation& seg, const std::string& kind) {
  int n = 0;
  for (const auto& s : seg.segments) n += s.kind == kind ? 1 : 0;
  return n;
}

TEST_CASE("a cluttered floor still segments into its rooms") {
  cv::Mat truth;
  OccupancyGrid grid = SyntheticFloor(&truth);
  auto fill = [&](double x0, double y0, double x1, double y1, std::uint8_t v) {
    cv::rectangle(grid.cells, Floor::R(x0, y0, x1, y1), cv::Scalar(v), cv::FILLED);
  };
  // Room 1: a 1.6 x 0.9 m table as a laser sees it: four legs and the unknown shadow between.
  fill(2.2, 4.4, 3.8, 5.3, kCellUnknown);
  for (const double x : {2.2, 3.7}) {
    for (const double y : {4.4, 5.2}) fill(x, y, x + 0.1, y + 0.1, kCellOccupied);
  }
  // Room 2: chairs (0.5 m outlines, staggered: collinear pieces closer than wall_line_gap_m
  // would read as a dashed wall) and a patch of floor the robot never saw.
  for (const double x : {5.8, 6.6, 7.4}) {
    const double y = x == 6.6 ? 3.8 : 4.6;
    cv::rectangle(grid.cells, Floor::R(x, y, x + 0.5, y + 0.5), cv::Scalar(kCellOccupied), 1);
  }
  fill(6.0, 5.6, 8.0, 6.4, kCellUnknown);
  // Room 3: a 0.8 m cabinet standing free; the corridor: a person.
  fill(10.5, 4.5, 11.3, 5.0, kCellOccupied);
  fill(6.0, 1.6, 6.3, 1.9, kCellOccupied);
  auto seg = SegmentRooms(grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 4);
  auto score = ScoreSegmentation(seg->labels, truth);
  REQUIRE(score.ok());
  CHECK(score->precision > 0.97);
  CHECK(score->recall > 0.97);
  CHECK(score->mean_iou > 0.95);
  CHECK(CountKind(*seg, "corridor") == 1);
  // Without decluttering the table's 1.4 m2 shadow stays an obstacle (the old behaviour).
  SegmentOptions off = Rules();
  off.cut.wall_min_length_m = 0.0;
  auto cluttered = SegmentRooms(grid, off);
  REQUIRE(cluttered.ok());
  CHECK(cv::countNonZero(cluttered->free_cleaned) < cv::countNonZero(seg->free_cleaned));
}

TEST_CASE("unknown cells inside a room do not split it") {
  Floor f(10.0, 7.0);
  f.Room(1.0, 1.0, 9.0, 6.0, 1);  // one 8 x 5 m room
  // Unseen floor: a 2.5 x 1.5 m patch in the middle and a 3 m band nearly across the room.
  f.Fill(3.5, 2.5, 6.0, 4.0, kCellUnknown);
  f.Fill(1.6, 4.6, 8.4, 5.0, kCellUnknown);
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 1);
  auto score = ScoreSegmentation(seg->labels, f.truth);
  REQUIRE(score.ok());
  CHECK(score->mean_iou > 0.95);
  // The unseen cells are part of the room's segment: the zone covers the whole room.
  CHECK(seg->labels.at<int>(Floor::kPx * 3, Floor::kPx * 5) > 0);
}

TEST_CASE("a corridor with rooms on both sides stays one corridor") {
  const Floor f = CorridorFloor();
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 11);
  CHECK(CountKind(*seg, "corridor") == 1);
  // One segment holds (nearly) all of the corridor.
  std::map<int, int> in_corridor;
  for (int r = 0; r < f.truth.rows; ++r) {
    for (int c = 0; c < f.truth.cols; ++c) {
      if (f.truth.at<int>(r, c) == 100) ++in_corridor[seg->labels.at<int>(r, c)];
    }
  }
  int best = 0, total = 0;
  for (const auto& [label, n] : in_corridor) {
    total += n;
    if (label > 0) best = std::max(best, n);
  }
  CHECK(best > 0.95 * total);
  auto score = ScoreSegmentation(seg->labels, f.truth);
  REQUIRE(score.ok());
  CHECK(score->mean_iou > 0.95);
}

// Corridor continuation (LearnedMergeOptions::layout_corridor_*, evaluated in issue 28's tenth
// round, off by default), at 0.1 m a cell with walls all round: a 1.4 m wide corridor of 12 m (1)
// continued by a 4 m stub (2), a 4 m wide room behind a 0.9 m door (3), a 2 m wide room behind a
// 0.6 m door (4), and a 3.4 m wide room open onto the corridor over its width, 1.4 m (5).
TEST_CASE("corridor continuation joins a corridor's pieces cut across, not rooms behind doors") {
  cv::Mat labels = cv::Mat::zeros(80, 175, CV_32S);
  labels(cv::Rect(45, 5, 120, 14)).setTo(1);
  labels(cv::Rect(5, 5, 40, 14)).setTo(2);
  labels(cv::Rect(50, 24, 40, 40)).setTo(3);
  labels(cv::Rect(65, 19, 9, 5)).setTo(3);
  labels(cv::Rect(95, 24, 20, 30)).setTo(4);
  labels(cv::Rect(101, 19, 6, 5)).setTo(4);
  labels(cv::Rect(125, 24, 34, 34)).setTo(5);
  labels(cv::Rect(135, 19, 14, 5)).setTo(5);
  const cv::Mat free = labels != 0;
  cv::Mat dt;
  cv::distanceTransform(free, dt, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const KindOptions kinds;
  const auto kind_of = [&](const cv::Mat& l, int count, int label) {
    return DescribeSegments(l, dt, count, 0.1, kinds)[static_cast<std::size_t>(label - 1)].kind;
  };
  REQUIRE(kind_of(labels, 5, 1) == "corridor");
  REQUIRE(kind_of(labels, 5, 2) == "room");  // a stub: too short to be a corridor by itself
  const auto corridor = [](const cv::Mat& l) { return l.at<int>(12, 100); };

  SUBCASE("off: nothing changes") {
    cv::Mat l = labels.clone();
    CHECK(MergeCorridors(&l, dt, 5, 0.1, kinds, 0.0, 1.5) == 5);
    CHECK(cv::countNonZero(l != labels) == 0);
  }
  SUBCASE("the stub joins its corridor; the doors and the wider room keep theirs apart") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeCorridors(&l, dt, 5, 0.1, kinds, 0.75, 1.5) == 4);
    CHECK(l.at<int>(12, 20) == corridor(l));   // the stub
    CHECK(l.at<int>(40, 70) != corridor(l));   // behind a 0.9 m door, 4 m wide
    CHECK(l.at<int>(40, 105) != corridor(l));  // 2 m wide, but behind a 0.6 m door
    CHECK(l.at<int>(40, 142) != corridor(l));  // open over 1.4 m, but over 1.5x as wide
    CHECK(kind_of(l, 4, corridor(l)) == "corridor");
  }
  SUBCASE("with any widths allowed the room open over its width joins too") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeCorridors(&l, dt, 5, 0.1, kinds, 0.75, 0.0) == 3);
    CHECK(l.at<int>(40, 142) == corridor(l));
    CHECK(l.at<int>(40, 105) != corridor(l));
  }
}

// Channel joins (LearnedMergeOptions::layout_channel_*, issue 28's fifteenth round), at 0.1 m a
// cell with walls all round: a 2 m wide corridor cut across into a west (1) and an east piece
// (2); a 4 m room behind a 0.9 m door (3); a 4 m room behind a 1.5 m opening in a 0.3 m wall (4);
// a 2 m branch meeting the corridor from the south (5); a 4 m office open onto the corridor over
// its whole front (6).
TEST_CASE("channel joins: a corridor cut across and its branch join; doors and open fronts not") {
  cv::Mat labels = cv::Mat::zeros(80, 215, CV_32S);
  labels(cv::Rect(5, 5, 60, 20)).setTo(1);
  labels(cv::Rect(65, 5, 145, 20)).setTo(2);
  labels(cv::Rect(20, 28, 40, 40)).setTo(3);
  labels(cv::Rect(35, 25, 9, 3)).setTo(3);
  labels(cv::Rect(70, 28, 40, 40)).setTo(4);
  labels(cv::Rect(80, 25, 15, 3)).setTo(4);
  labels(cv::Rect(125, 25, 20, 50)).setTo(5);
  labels(cv::Rect(160, 25, 40, 40)).setTo(6);
  const cv::Mat free = labels != 0;
  const auto at = [](const cv::Mat& l, int x, int y) { return l.at<int>(y, x); };

  SUBCASE("off: nothing changes") {
    cv::Mat l = labels.clone();
    CHECK(MergeChannels(&l, free, 6, 0.1, 0.0, 1.2) == 6);
    CHECK(cv::countNonZero(l != labels) == 0);
  }
  SUBCASE("the corridor's two pieces and its branch become one; the rooms keep theirs") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeChannels(&l, free, 6, 0.1, 1.0, 1.2) == 4);
    const int corridor = at(l, 100, 15);
    CHECK(at(l, 20, 15) == corridor);   // the west piece, across the cut
    CHECK(at(l, 135, 60) == corridor);  // the branch, across the T
    CHECK(at(l, 40, 50) != corridor);   // behind a 0.9 m door: narrower than a corridor
    CHECK(at(l, 90, 50) != corridor);   // behind a 1.5 m opening: the room opens sideways
    CHECK(at(l, 180, 50) != corridor);  // open over 4 m: wider than a corridor
    CHECK(at(l, 40, 50) != at(l, 90, 50));
  }
  SUBCASE("a depth within the wall's thickness takes the opening for a channel") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeChannels(&l, free, 6, 0.1, 0.2, 1.2) == 3);
    CHECK(at(l, 90, 50) == at(l, 100, 15));
  }
  SUBCASE("the median width test joins the same: doors and rooms are wider past the border") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeChannels(&l, free, 6, 0.1, 1.0, 1.2, 1.5) == 4);
    const int corridor = at(l, 100, 15);
    CHECK(at(l, 20, 15) == corridor);
    CHECK(at(l, 135, 60) == corridor);
    CHECK(at(l, 90, 50) != corridor);
  }
  SUBCASE("a branch narrower than the minimum width is a door") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeChannels(&l, free, 6, 0.1, 1.0, 2.5) == 6);
  }
}

// MergeSmallSegments numbers what is left 1..N in label order: a speck joins the neighbour it
// shares most border with, an isolated speck is dropped, and labels with no cells (left by the
// merges before it) get no number, also with min_area 0, where it only renumbers.
TEST_CASE("small segments merge into their longest neighbour and labels end dense") {
  cv::Mat labels = cv::Mat::zeros(20, 40, CV_32S);
  labels(cv::Rect(0, 0, 10, 10)).setTo(2);   // 100 cells
  labels(cv::Rect(10, 0, 10, 10)).setTo(5);  // 100 cells
  labels(cv::Rect(10, 10, 2, 3)).setTo(6);   // a speck: 2 cells of border with 5, 3 with 7
  labels(cv::Rect(12, 10, 8, 10)).setTo(7);  // 80 cells
  labels(cv::Rect(30, 15, 2, 2)).setTo(8);   // an isolated speck
  // labels 1, 3 and 4 have no cells
  SUBCASE("min_area 0: renumbered densely, nothing merged") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeSmallSegments(&l, 8, 0) == 5);
    CHECK(l.at<int>(0, 0) == 1);
    CHECK(l.at<int>(0, 10) == 2);
    CHECK(l.at<int>(10, 10) == 3);
    CHECK(l.at<int>(10, 12) == 4);
    CHECK(l.at<int>(15, 30) == 5);
  }
  SUBCASE("min_area 10: the speck joins its longest border, the isolated one is dropped") {
    cv::Mat l = labels.clone();
    REQUIRE(MergeSmallSegments(&l, 8, 10) == 3);
    CHECK(l.at<int>(10, 10) == l.at<int>(10, 12));  // 3 cells of border with 7 against 2 with 5
    CHECK(l.at<int>(10, 12) == 3);
    CHECK(l.at<int>(15, 30) == 0);
    double max_label = 0.0;
    cv::minMaxLoc(l, nullptr, &max_label);
    CHECK(max_label == 3.0);
  }
}

// The share of `truth` label `label`'s cells held by its best segment, and that segment.
double BestShare(const Segmentation& seg, const cv::Mat& truth, int label, int* best_label) {
  std::map<int, int> count;
  int total = 0;
  for (int r = 0; r < truth.rows; ++r) {
    for (int c = 0; c < truth.cols; ++c) {
      if (truth.at<int>(r, c) != label) continue;
      ++total;
      const int l = seg.labels.at<int>(r, c);
      if (l > 0) ++count[l];
    }
  }
  int best = 0;
  *best_label = 0;
  for (const auto& [l, n] : count) {
    if (n > best) best = n, *best_label = l;
  }
  return total > 0 ? static_cast<double>(best) / total : 0.0;
}

TEST_CASE("rooms joined by open-plan openings of 1.5 to 3 m split into the rooms") {
  // An apartment row: four rooms side by side, 5 to 6 m wide and 6 m deep, the partitions
  // between them opened over 1.5 m and 2.0 m (wall on both sides of the opening) and 3.0 m (a
  // sliding partition from a wall stub to the outer wall: wall on one side only). An opening
  // stays a border when it is narrower than opening_merge_ratio (0.6) x the larger room's
  // width: here at most 3.0 / 6.0 = 0.5.
  Floor f(25.5, 8.0);
  const double x[5] = {1.0, 6.6, 12.2, 18.3, 24.5};
  for (int i = 0; i < 4; ++i) f.Room(x[i], 1.0, x[i + 1] - 0.1, 7.0, i + 1);
  f.Fill(x[1] - 0.1, 2.5, x[1], 4.0, kCellFree);   // 1.5 m, wall on both sides
  f.Fill(x[2] - 0.1, 3.0, x[2], 5.0, kCellFree);   // 2.0 m, wall on both sides
  f.Fill(x[3] - 0.1, 4.05, x[3], 7.0, kCellFree);  // 3.0 m, from a 3 m stub to the outer wall
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 4);
  std::set<int> used;
  for (int i = 1; i <= 4; ++i) {
    int l = 0;
    CHECK(BestShare(*seg, f.truth, i, &l) > 0.93);
    used.insert(l);
  }
  CHECK(used.size() == 4);  // each room its own segment
  auto score = ScoreSegmentation(seg->labels, f.truth);
  REQUIRE(score.ok());
  CHECK(score->mean_iou > 0.9);
  // Without the layout step the same floor is one or two segments (the openings are too wide
  // for doors and too wide to narrow the clearance much).
  SegmentOptions off = Rules();
  off.cut.opening_max_width_m = 0.0;
  auto without = SegmentRooms(f.grid, off);
  REQUIRE(without.ok());
  CHECK(without->segments.size() < 4);
}

TEST_CASE("an opening that constricts neither side joins the two spaces") {
  // A 6 x 3.5 m room with a 0.6 m partial wall from the middle of one long side (a stub: shorter
  // than a wall run, joined to the wall): its free end is continued to the far wall (an opening
  // of 2.9 m), open over 0.83 of the 3.5 m beside it and as wide as either half: no
  // constriction, one room (a corridor crossed by an aligned wall, likewise).
  Floor f(8.0, 5.5);
  f.Room(1.0, 1.0, 7.0, 4.5, 1);
  f.Fill(3.95, 1.0, 4.05, 1.6, kCellOccupied);
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 1);
  int l = 0;
  CHECK(BestShare(*seg, f.truth, 1, &l) > 0.95);  // less the partial wall
  // With the local ratio above 0.83 the opening stays a border: the partial wall did make one.
  SegmentOptions strict = Rules();
  strict.rules.opening_local_ratio = 0.9;
  auto split = SegmentRooms(f.grid, strict);
  REQUIRE(split.ok());
  CHECK(split->segments.size() == 2);
  // A partial wall over 2 m of the 3.5 m (an opening of 1.5 m, 0.43 of the space beside it) is
  // a partition with the default local ratio (0.75): two rooms.
  Floor g(8.0, 5.5);
  g.Room(1.0, 1.0, 7.0, 4.5, 1);
  g.Fill(3.95, 1.0, 4.05, 3.0, kCellOccupied);
  auto parts = SegmentRooms(g.grid, Rules());
  REQUIRE(parts.ok());
  CHECK(parts->segments.size() == 2);
}

TEST_CASE("an apartment with a sliding partition, a balcony slider and a WC splits") {
  // A 6 x 4.5 m living room; right of it a 3.5 x 4.5 m kitchen behind a partition that is
  // open over 2.5 m (a sliding door: 2.0 m of wall from the top, open to the bottom wall);
  // below it a 1.5 m deep balcony behind a 2.4 m slider in the outer wall (wall on both
  // sides); above it a 1.5 x 1.2 m WC behind a 0.7 m door. The openings are 2.5 / 4.5 = 0.56
  // and 2.4 / 6.0 = 0.4 of the space beside them: borders.
  Floor f(13.0, 10.5);
  f.Room(1.0, 3.0, 7.0, 7.5, 1);          // living room
  f.Room(7.1, 3.0, 10.6, 7.5, 2);         // kitchen
  f.Room(1.0, 7.6, 7.0, 9.1, 3);          // balcony
  f.Room(1.0, 1.0, 2.5, 2.2, 4);          // WC (1.5 x 1.2 m)
  f.Fill(7.0, 5.0, 7.1, 7.5, kCellFree);  // the sliding door: 2.5 m open at the bottom
  f.Fill(2.8, 7.5, 5.2, 7.6, kCellFree);  // the balcony slider, 2.4 m
  f.Fill(1.5, 2.2, 2.2, 3.0, kCellFree);  // WC door, 0.7 m
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  std::set<int> used;
  for (int i = 1; i <= 4; ++i) {
    int l = 0;
    CHECK_MESSAGE(BestShare(*seg, f.truth, i, &l) > 0.85, "room " << i);
    used.insert(l);
  }
  CHECK(used.size() == 4);  // each its own segment
  CHECK(seg->segments.size() <= 5);
}

TEST_CASE("a wardrobe behind a door in a wall of short pieces is a room of its own") {
  // A 4 x 3 m room with a 1.6 x 0.7 m wardrobe against its top wall, behind a 0.8 m door: the
  // wardrobe's front wall is two 0.5 m pieces, shorter than a wall run (1 m), and the wardrobe
  // is too narrow for any seed level (0.35 m clearance). Stubs close its door (a doorway
  // between the two pieces) and the space they enclose is a seedless room.
  Floor f(6.0, 5.0);
  f.Room(1.0, 1.0, 5.0, 4.0, 1);
  f.Fill(1.9, 1.0, 3.7, 1.8, kCellOccupied);
  f.Room(2.0, 1.0, 3.6, 1.7, 2);
  f.Fill(2.4, 1.7, 3.2, 1.8, kCellFree);
  SegmentOptions o = Rules();
  o.cut.wall_stub_min_length_m = 0.3;
  o.cut.seedless_room_min_area_m2 = 0.5;
  o.rules.min_room_area_m2 = 0.5;
  auto seg = SegmentRooms(f.grid, o);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  int l1 = 0, l2 = 0;
  CHECK(BestShare(*seg, f.truth, 1, &l1) > 0.9);  // less the wardrobe's walls
  CHECK(BestShare(*seg, f.truth, 2, &l2) > 0.85);
  CHECK(l1 != l2);
  // Without stubs the door stays open and the wardrobe is flooded from the room.
  SegmentOptions no_stubs = o;
  no_stubs.cut.wall_stub_min_length_m = 0.0;
  auto merged = SegmentRooms(f.grid, no_stubs);
  REQUIRE(merged.ok());
  BestShare(*merged, f.truth, 1, &l1);
  BestShare(*merged, f.truth, 2, &l2);
  CHECK(l1 == l2);
}

// Room 2 of `f` is a segment of its own (holding `share` of it) beside room 1 with the default
// options, and is flooded from room 1 with `rule_off` (the rule that finds it turned off).
void CheckOwnRoomOnlyWithRule(const Floor& f, double share, const SegmentOptions& rule_off) {
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  int l1 = 0, l2 = 0;
  CHECK(BestShare(*seg, f.truth, 1, &l1) > 0.9);
  CHECK(BestShare(*seg, f.truth, 2, &l2) > share);
  CHECK(l1 != l2);
  auto merged = SegmentRooms(f.grid, rule_off);
  REQUIRE(merged.ok());
  BestShare(*merged, f.truth, 1, &l1);
  BestShare(*merged, f.truth, 2, &l2);
  CHECK(l1 == l2);
}

TEST_CASE("a balcony behind a full-width slider, protruding from the facade, is its own zone") {
  // A 6 x 4 m flat drawn as a plan (0.15 m walls, the outside unknown) with a 2.5 x 1 m balcony
  // protruding below it; the slider spans the balcony's whole width, so no wall piece stands
  // in its mouth and the balcony is too shallow for a seed of its own. The facade pieces either
  // side of the mouth, continued across it, close it (round 4 of issue 16).
  Floor f(9.0, 8.0);
  f.Fill(0.0, 0.0, 9.0, 8.0, kCellUnknown);
  f.Fill(0.85, 0.85, 7.15, 5.15, kCellOccupied);
  f.Fill(2.35, 5.0, 5.15, 6.3, kCellOccupied);
  f.Room(1.0, 1.0, 7.0, 5.0, 1);
  f.Room(2.5, 5.15, 5.0, 6.15, 2);
  f.Fill(2.5, 5.0, 5.0, 5.15, kCellFree);  // the slider, open
  // Without facade openings the balcony is flooded from the room.
  SegmentOptions off = Rules();
  off.cut.facade_opening_max_width_m = 0.0;
  CheckOwnRoomOnlyWithRule(f, /*share=*/0.85, off);
}

TEST_CASE("a wardrobe whose whole front is one door is a room of its own") {
  // The mouth between the two side walls' aligned free ends closes it (round 4 of issue 16).
  const Floor f = WardrobeFloor();
  SegmentOptions off = Rules();
  off.cut.mouth_opening_max_width_m = 0.0;
  CheckOwnRoomOnlyWithRule(f, /*share=*/0.8, off);
}

TEST_CASE("an L-shaped room and a room with furniture against its walls stay whole") {
  const Floor f = LShapedFloor();
  auto seg = SegmentRooms(f.grid, Rules());
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 2);
  int l1 = 0, l2 = 0;
  CHECK(BestShare(*seg, f.truth, 1, &l1) > 0.95);
  CHECK(BestShare(*seg, f.truth, 2, &l2) > 0.85);  // less the furniture
  CHECK(l1 != l2);
}

// The default: layout pieces merged by the compiled-in model (layout_merge.h). The same floors
// as the rule tests above; the model was trained on real plans, never on these.
TEST_CASE("the default layout merge: rooms joined by doors, one segment per room") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  auto seg = SegmentRooms(grid);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  auto score = ScoreSegmentation(seg->labels, truth);
  REQUIRE(score.ok());
  MESSAGE("synthetic floor, layout merge: " << score->precision << " " << score->recall << " "
                                            << score->mean_iou << " " << score->predicted_segments);
  CHECK(score->predicted_segments == 4);
  CHECK(score->precision > 0.99);
  CHECK(score->recall > 0.99);
  CHECK(score->mean_iou > 0.98);
  CHECK(CountKind(*seg, "corridor") == 1);
}

TEST_CASE("the default layout merge: a corridor crossed by aligned walls stays one") {
  const Floor f = CorridorFloor();
  auto seg = SegmentRooms(f.grid);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  int corridor_label = 0;
  CHECK(BestShare(*seg, f.truth, 100, &corridor_label) > 0.95);
  std::set<int> room_labels;
  for (int id : {1, 2, 3, 4, 5, 11, 12, 13, 14, 15}) {
    int label = 0;
    CHECK(BestShare(*seg, f.truth, id, &label) > 0.95);
    room_labels.insert(label);
  }
  CHECK(room_labels.size() == 10);
  CHECK(room_labels.count(corridor_label) == 0);
}

// The median width test (layout_channel_median_width_ratio, issue 28's seventeenth round), at
// 0.1 m a cell: a 2 m wide corridor cut across into a west (1) and an east piece (2), an open
// 0.8 m door in its south wall just west of the cut into a room (3) and one in its north wall
// just east of it into another (4). The doors break the walls beside the cut's ends for 8 of
// 20 steps each way: the walls test fails; the corridor keeps its width at the other 12.
TEST_CASE("channel joins: the median width passes over open doors the walls test fails on") {
  cv::Mat labels = cv::Mat::zeros(60, 140, CV_32S);
  labels(cv::Rect(5, 20, 60, 20)).setTo(1);
  labels(cv::Rect(65, 20, 60, 20)).setTo(2);
  labels(cv::Rect(40, 43, 40, 17)).setTo(3);
  labels(cv::Rect(52, 40, 8, 3)).setTo(3);
  labels(cv::Rect(60, 0, 40, 17)).setTo(4);
  labels(cv::Rect(70, 17, 8, 3)).setTo(4);
  const cv::Mat free = labels != 0;
  cv::Mat walls = labels.clone();
  CHECK(MergeChannels(&walls, free, 4, 0.1, 2.0, 1.2) == 4);
  cv::Mat median = labels.clone();
  REQUIRE(MergeChannels(&median, free, 4, 0.1, 2.0, 1.2, 1.5) == 3);
  CHECK(median.at<int>(30, 20) == median.at<int>(30, 110));  // the corridor is one
  CHECK(median.at<int>(50, 60) != median.at<int>(30, 20));   // behind a door: narrower
  CHECK(median.at<int>(8, 80) != median.at<int>(30, 20));
}

TEST_CASE("channel joins leave a drawn plan's zones alone: they are for rough grids only") {
  // The corridor floor's pieces with a model that merges none: its corridor is cut across where
  // the rooms' walls meet it, cuts the channel rule joins when called on them...
  const Floor f = CorridorFloor();
  REQUIRE(GridRoughFaceShare(f.grid) <= 0.3);  // the compiled-in model's gate
  const SegmentOptions off;
  SegmentOptions on;
  on.learned.layout_channel_depth_m = 1.0;
  auto pieces_off = SegmentRooms(f.grid, off, NeverMerges(off));
  auto pieces_on = SegmentRooms(f.grid, on, NeverMerges(on));
  REQUIRE_MESSAGE(pieces_off.ok(), pieces_off.status().ToString());
  REQUIRE_MESSAGE(pieces_on.ok(), pieces_on.status().ToString());
  cv::Mat l = pieces_off->labels.clone();
  const int n = static_cast<int>(pieces_off->segments.size());
  CHECK(MergeChannels(&l, f.grid.cells == kCellFree, n, 0.05, 1.0, 1.2) < n);
  // ...but not in SegmentRooms: the grid is a drawn plan, below the gate, before the model or
  // after it.
  CHECK(cv::countNonZero(pieces_on->labels != pieces_off->labels) == 0);
  on.learned.layout_channel_before_model = 1.0;
  auto first = SegmentRooms(f.grid, on, NeverMerges(on));
  REQUIRE_MESSAGE(first.ok(), first.status().ToString());
  CHECK(cv::countNonZero(first->labels != pieces_off->labels) == 0);
}

TEST_CASE("the default layout merge: an L-shaped room stays whole") {
  const Floor f = LShapedFloor();
  auto seg = SegmentRooms(f.grid);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  int l1 = 0, l2 = 0;
  CHECK(BestShare(*seg, f.truth, 1, &l1) > 0.95);
  CHECK(BestShare(*seg, f.truth, 2, &l2) > 0.85);
  CHECK(l1 != l2);
}

TEST_CASE(
    "the layout pieces are the rule borders and more, a model that merges nothing keeps "
    "them all") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  auto pieces = SegmentRooms(grid, SegmentOptions{}, NeverMerges(SegmentOptions{}));
  auto merged = SegmentRooms(grid);
  auto rules = SegmentRooms(grid, Rules());
  REQUIRE(pieces.ok());
  REQUIRE(merged.ok());
  REQUIRE(rules.ok());
  CHECK(pieces->segments.size() >= merged->segments.size());
  CHECK(pieces->segments.size() >= rules->segments.size());
  // Every labelled cell is free in the cleaned grid, whatever merges.
  for (int r = 0; r < pieces->labels.rows; ++r) {
    for (int c = 0; c < pieces->labels.cols; ++c) {
      if (pieces->labels.at<int>(r, c) > 0) {
        CHECK(pieces->free_cleaned.at<std::uint8_t>(r, c) == 255);
      }
    }
  }
}

TEST_CASE("the learned merge refuses cut options its model was not trained with") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  SegmentOptions o;
  o.cut.door_max_width_m = 0.9;
  auto refused = SegmentRooms(grid, o);
  REQUIRE_FALSE(refused.ok());
  CHECK(refused.status().message().find("door_max_width_m=1.2, these options have 0.9") !=
        std::string::npos);
  o.learned.layout_merge_threshold = 0.0;  // the rule merges use no model
  CHECK(SegmentRooms(grid, o).ok());
}

// map15's score with `options`, or none, saying so, when the shared data are not there (they
// sit beside the checkout; a worktree elsewhere points at them with ZM_SHARED_DIR).
std::optional<SegmentationScore> Map15Score(const SegmentOptions& options) {
  const char* env = std::getenv("ZM_SHARED_DIR");
  const std::string base =
      std::string(env != nullptr ? env : ZM_SHARED_DIR) + "/data/floorplans/map15";
  if (!std::filesystem::exists(base + "_map.png")) {
    MESSAGE("skipped: no shared floor plan at " << base << "_map.png (set ZM_SHARED_DIR)");
    return std::nullopt;
  }
  auto grid = LoadGridImage(base + "_map.png");
  REQUIRE_MESSAGE(grid.ok(), grid.status().ToString());
  auto gt = LoadGroundTruthLabels(base + "_gt.png");
  REQUIRE(gt.ok());
  auto seg = SegmentRooms(*grid, options);
  REQUIRE(seg.ok());
  auto score = ScoreSegmentation(seg->labels, *gt);
  REQUIRE(score.ok());
  MESSAGE("map15: " << score->precision << " / " << score->recall << " / " << score->mean_iou
                    << ", " << score->predicted_segments << " segments");
  return *score;
}

// SCORING REGRESSION FLOOR, not a tuning target: the defaults were chosen by leave-one-out on
// the six shared maps (docs/segmentation.md). map15 measured 96.1 / 95.2 / 83.5 % with 23
// segments (98.4 / 86.9 / 81.6 % with 25 before the layout step); these floors sit a few points
// below both so that only a real regression trips them.
TEST_CASE("regression floor: map15 with the rule merges") {
  const auto score = Map15Score(Rules());
  if (!score) return;
  CHECK(score->gt_rooms == 20);
  // Third part of issue 16 (stubs, seedless rooms, local opening measure): measured 87.3 /
  // 85.1 / 74.3 %, down from 96.1 / 95.2 / 83.5 (docs/segmentation.md: a trade on this map).
  // Fourth part (facade, mouths, facing ends; a border's main opening decides): 94.3 / 83.0 /
  // 77.8 % with 37 segments (31 before): door recesses and closets are segments of their own.
  CHECK(score->precision >= 0.90);
  CHECK(score->recall >= 0.80);
  CHECK(score->mean_iou >= 0.75);
  CHECK(score->predicted_segments >= 16);
  CHECK(score->predicted_segments <= 40);
}

// SCORING REGRESSION FLOOR for the default (the learned layout merge). map15 is a robot-made grid
// (above the model's gate, map_rough_face_share 0.3), so since issue 28's twelfth round the
// robot half (L bag5) merges it: measured 87.5 / 93.9 / 81.6 % with 24 segments (the shipped
// trees alone, issue 16 sixth part: 93.1 / 94.1 / 88.5 %, 27). The compiled-in model saw map15 in
// training, so this is a floor, not an evaluation; the leave-one-out figures (75.7 % under the
// robot half, 72.4 under the shipped trees) are in docs/segmentation.md.
TEST_CASE("regression floor: map15 with the default options (the layout merge)") {
  const auto score = Map15Score(SegmentOptions{});
  if (!score) return;
  CHECK(score->gt_rooms == 20);
  CHECK(score->precision >= 0.84);
  CHECK(score->recall >= 0.90);
  CHECK(score->mean_iou >= 0.78);
  CHECK(score->predicted_segments >= 20);
  CHECK(score->predicted_segments <= 50);
}

TEST_CASE("a GT room the map never shows is left out of mean_iou_shown, not of mean_iou") {
  // Three GT rooms side by side, 20 x 20 cells each; the map shows the first two as free, of the
  // third only 150 cells (under the 200 that make a room). The segmentation has the first two
  // exactly and nothing of the third.
  cv::Mat truth = cv::Mat::zeros(20, 60, CV_32S);
  truth(cv::Rect(0, 0, 20, 20)).setTo(1);
  truth(cv::Rect(20, 0, 20, 20)).setTo(2);
  truth(cv::Rect(40, 0, 20, 20)).setTo(3);
  cv::Mat predicted = cv::Mat::zeros(20, 60, CV_32S);
  predicted(cv::Rect(0, 0, 20, 20)).setTo(7);
  predicted(cv::Rect(20, 0, 20, 20)).setTo(8);
  cv::Mat free_cells = cv::Mat::zeros(20, 60, CV_8U);
  free_cells(cv::Rect(0, 0, 40, 20)).setTo(255);
  free_cells(cv::Rect(40, 0, 15, 10)).setTo(255);
  auto score = ScoreSegmentation(predicted, truth, free_cells);
  REQUIRE(score.ok());
  CHECK(score->gt_rooms == 3);
  CHECK(score->gt_rooms_shown == 2);
  CHECK(score->mean_iou == doctest::Approx(2.0 / 3.0));
  CHECK(score->mean_iou_shown == doctest::Approx(1.0));
  CHECK(score->precision == doctest::Approx(1.0));
  CHECK(score->recall == doctest::Approx(1.0));
  // Once the map shows 200 cells of the third room, missing it costs again.
  free_cells(cv::Rect(40, 0, 20, 10)).setTo(255);
  score = ScoreSegmentation(predicted, truth, free_cells);
  REQUIRE(score.ok());
  CHECK(score->gt_rooms_shown == 3);
  CHECK(score->mean_iou_shown == doctest::Approx(2.0 / 3.0));
  // Without a map every GT room counts: the two means agree.
  score = ScoreSegmentation(predicted, truth);
  REQUIRE(score.ok());
  CHECK(score->gt_rooms_shown == 3);
  CHECK(score->mean_iou_shown == doctest::Approx(score->mean_iou));
  CHECK_FALSE(ScoreSegmentation(predicted, truth, cv::Mat::zeros(20, 60, CV_32F)).ok());
}

TEST_CASE("bad inputs give one clear error naming the file") {
  const auto dir = TempDir("bad");
  auto missing = LoadOccupancyGrid((dir / "nope.png").string());
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().code() == StatusCode::kNotFound);
  CHECK(missing.status().message().find("nope.png") != std::string::npos);

  const std::string text = (dir / "text.png").string();
  std::ofstream(text) << "this is not an image\n";
  auto not_image = LoadOccupancyGrid(text);
  REQUIRE_FALSE(not_image.ok());
  CHECK(not_image.status().message().find("not a readable image") != std::string::npos);

  cv::imwrite((dir / "map.pgm").string(), cv::Mat(4, 4, CV_8UC1, cv::Scalar(254)));
  const std::string bad_res = (dir / "bad_res.yaml").string();
  std::ofstream(bad_res) << "image: map.pgm\nresolution: -0.05\norigin: [0, 0, 0]\n";
  auto res = LoadOccupancyGrid(bad_res);
  REQUIRE_FALSE(res.ok());
  CHECK(res.status().message().find("resolution") != std::string::npos);
  CHECK(res.status().message().find("bad_res.yaml:2") != std::string::npos);

  const std::string unknown = (dir / "unknown.yaml").string();
  std::ofstream(unknown) << "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\ncolour: red\n";
  auto unk = LoadOccupancyGrid(unknown);
  REQUIRE_FALSE(unk.ok());
  CHECK(unk.status().message().find("unknown key 'colour'") != std::string::npos);

  CHECK_FALSE(LoadGridImage(text, 0.0).ok());
  CHECK_FALSE(LoadGroundTruthLabels((dir / "gt_missing.png").string()).ok());
}

// Issue 28's bad input: a map with no free space, a single room, a huge grid around a small
// building, a huge known area, a non-binary image (the negative resolution is the YAML case
// above). Each gives one clear error or a sensible zone, never a crash.
TEST_CASE("a grid with no free cell is one clear error, not an empty zone file") {
  for (const std::uint8_t fill : {kCellOccupied, kCellUnknown}) {
    OccupancyGrid grid;
    grid.cells = cv::Mat(60, 80, CV_8UC1, cv::Scalar(fill));
    auto seg = SegmentRooms(grid);
    REQUIRE_FALSE(seg.ok());
    CHECK(seg.status().code() == StatusCode::kFailedPrecondition);
    CHECK(seg.status().message().find("no free cell") != std::string::npos);
    CHECK(seg.status().message().find("80 x 60 cells") != std::string::npos);
  }
}

// A 5 x 4 m room with 0.1 m walls in a grid of `side` x `side` unknown cells, at (col, row).
OccupancyGrid LoneRoom(int side, int col, int row) {
  OccupancyGrid grid;
  grid.cells = cv::Mat(side, side, CV_8UC1, cv::Scalar(kCellUnknown));
  cv::rectangle(grid.cells, cv::Rect(col, row, 102, 82), cv::Scalar(kCellOccupied), cv::FILLED);
  cv::rectangle(grid.cells, cv::Rect(col + 2, row + 2, 98, 78), cv::Scalar(kCellFree), cv::FILLED);
  return grid;
}

TEST_CASE("a single room is one zone, also in a grid a hundred times its size") {
  const OccupancyGrid alone = LoneRoom(120, 10, 20);
  auto one = SegmentRooms(alone);
  REQUIRE_MESSAGE(one.ok(), one.status().ToString());
  REQUIRE(one->segments.size() == 1);
  CHECK(one->segments[0].area_m2 == doctest::Approx(98 * 78 * 0.0025).epsilon(0.03));
  // The same room far inside 3000 x 3000 cells (150 m a side) of unknown: only the known part
  // is segmented, and the labels come back in the big grid's cells.
  const OccupancyGrid big = LoneRoom(3000, 1700, 2100);
  auto far = SegmentRooms(big);
  REQUIRE_MESSAGE(far.ok(), far.status().ToString());
  REQUIRE(far->segments.size() == 1);
  CHECK(far->labels.size() == big.cells.size());
  CHECK(far->segments[0].area_cells == one->segments[0].area_cells);
  CHECK(cv::countNonZero(far->labels(cv::Rect(1700, 2100, 102, 82)) != 0) ==
        one->segments[0].area_cells);
  CHECK(cv::countNonZero(far->labels) == one->segments[0].area_cells);
  // The zone's polygon is in the big grid's map frame.
  auto zones = SegmentationToZones(*far, big);
  REQUIRE(zones.ok());
  REQUIRE(zones->size() == 1);
  const auto& ring = (*zones)[0].polygon;
  double x_min = 1e9, y_min = 1e9;
  for (const auto& p : ring) x_min = std::min(x_min, p.x()), y_min = std::min(y_min, p.y());
  CHECK(x_min == doctest::Approx(1702 * 0.05).epsilon(0.01));
  CHECK(y_min == doctest::Approx((3000 - 2100 - 80) * 0.05).epsilon(0.01));
}

TEST_CASE("a known part larger than kMaxSegmentCells is refused, naming its size and the limit") {
  OccupancyGrid grid;
  grid.cells = cv::Mat(5000, 6002, CV_8UC1, cv::Scalar(kCellUnknown));
  grid.cells.at<std::uint8_t>(10, 10) = kCellFree;
  grid.cells.at<std::uint8_t>(4990, 5990) = kCellOccupied;
  auto seg = SegmentRooms(grid);
  REQUIRE_FALSE(seg.ok());
  CHECK(seg.status().code() == StatusCode::kInvalidArgument);
  CHECK(seg.status().message().find("6002 x 5000 cells") != std::string::npos);
  CHECK(seg.status().message().find(std::to_string(kMaxSegmentCells)) != std::string::npos);
}

TEST_CASE("a non-binary image is read by thresholds and segments without error") {
  const auto dir = TempDir("grey");
  // A grey ramp (0..255 across) and a colour photo-like image: only >= 250 is free.
  cv::Mat ramp(200, 300, CV_8UC1);
  for (int c = 0; c < ramp.cols; ++c) ramp.col(c).setTo(cv::Scalar(c * 255 / (ramp.cols - 1)));
  cv::imwrite((dir / "ramp.png").string(), ramp);
  auto grid = LoadOccupancyGrid((dir / "ramp.png").string());
  REQUIRE_MESSAGE(grid.ok(), grid.status().ToString());
  const int free_cells = cv::countNonZero(grid->cells == kCellFree);
  CHECK(free_cells > 0);
  CHECK(free_cells < 200 * 10);  // the few brightest columns
  auto seg = SegmentRooms(*grid);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK(seg->segments.size() == 1);
  cv::Mat colour(200, 300, CV_8UC3, cv::Scalar(90, 200, 30));
  cv::imwrite((dir / "colour.png").string(), colour);
  auto photo = LoadOccupancyGrid((dir / "colour.png").string());
  REQUIRE_MESSAGE(photo.ok(), photo.status().ToString());
  auto none = SegmentRooms(*photo);  // no free cell in it: the clear error above
  REQUIRE_FALSE(none.ok());
  CHECK(none.status().message().find("no free cell") != std::string::npos);
}

TEST_CASE("ROS YAML grids follow map_server thresholds and place cells with y up") {
  const auto dir = TempDir("yaml");
  cv::Mat img(2, 3, CV_8UC1);
  img.at<std::uint8_t>(0, 0) = 254;  // free
  img.at<std::uint8_t>(0, 1) = 0;    // occupied
  img.at<std::uint8_t>(0, 2) = 205;  // unknown (p = 0.196..0.65)
  img.at<std::uint8_t>(1, 0) = 0;
  img.at<std::uint8_t>(1, 1) = 254;
  img.at<std::uint8_t>(1, 2) = 254;
  cv::imwrite((dir / "m.pgm").string(), img);
  const std::string yaml = (dir / "m.yaml").string();
  std::ofstream(yaml) << "# a map\nimage: m.pgm\nresolution: 0.5\norigin: [-1.0, 2.0, 0.0]\n"
                         "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n";
  auto grid = LoadOccupancyGrid(yaml);
  REQUIRE_MESSAGE(grid.ok(), grid.status().ToString());
  CHECK(grid->cells.at<std::uint8_t>(0, 0) == kCellFree);
  CHECK(grid->cells.at<std::uint8_t>(0, 1) == kCellOccupied);
  CHECK(grid->cells.at<std::uint8_t>(0, 2) == kCellUnknown);
  CHECK(grid->cells.at<std::uint8_t>(1, 0) == kCellOccupied);
  // Bottom-left cell (col 0, row 1) has its centre half a cell from the origin.
  const Eigen::Vector2d p = grid->CellToMetres(0, 1);
  CHECK(p.x() == doctest::Approx(-0.75));
  CHECK(p.y() == doctest::Approx(2.25));
  int col = -1, row = -1;
  REQUIRE(grid->CellOf({0.1, 2.9}, &col, &row));  // top row, middle column
  CHECK(col == 2);
  CHECK(row == 0);
  CHECK_FALSE(grid->CellOf({-1.1, 2.1}, &col, &row));
}

TEST_CASE("an RTAB-Map database's Admin.opt_map becomes a grid, flipped to y up") {
  const auto dir = TempDir("rtabmap");
  const std::string db_path = (dir / "rtabmap.db").string();
  // 2 rows x 3 cols int8, RTAB-Map row 0 = lowest y.
  const std::int8_t cells[6] = {0, 100, -1, 100, 0, 0};
  uLongf bound = compressBound(sizeof(cells));
  std::string blob(bound, '\0');
  REQUIRE(compress(reinterpret_cast<Bytef*>(blob.data()), &bound,
                   reinterpret_cast<const Bytef*>(cells), sizeof(cells)) == Z_OK);
  blob.resize(bound);
  const std::int32_t trailer[3] = {2, 3, CV_8SC1};
  blob.append(reinterpret_cast<const char*>(trailer), sizeof(trailer));

  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open(db_path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db,
                       "CREATE TABLE Admin (version TEXT, opt_map BLOB, opt_map_x_min FLOAT, "
                       "opt_map_y_min FLOAT, opt_map_resolution FLOAT)",
                       nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  REQUIRE(sqlite3_prepare_v2(db, "INSERT INTO Admin VALUES ('0.21.0', ?, -2.0, 3.0, 0.1)", -1,
                             &stmt, nullptr) == SQLITE_OK);
  sqlite3_bind_blob(stmt, 1, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
  REQUIRE(sqlite3_step(stmt) == SQLITE_DONE);
  sqlite3_finalize(stmt);
  sqlite3_close(db);

  auto grid = LoadOccupancyGrid(db_path);
  REQUIRE_MESSAGE(grid.ok(), grid.status().ToString());
  REQUIRE(grid->rows() == 2);
  REQUIRE(grid->cols() == 3);
  CHECK(grid->resolution_m == doctest::Approx(0.1));
  // RTAB-Map row 0 is our bottom row (image row 1).
  CHECK(grid->cells.at<std::uint8_t>(1, 0) == kCellFree);
  CHECK(grid->cells.at<std::uint8_t>(1, 1) == kCellOccupied);
  CHECK(grid->cells.at<std::uint8_t>(1, 2) == kCellUnknown);
  CHECK(grid->cells.at<std::uint8_t>(0, 0) == kCellOccupied);
  const Eigen::Vector2d p = grid->CellToMetres(0, 1);
  CHECK(p.x() == doctest::Approx(-1.95));
  CHECK(p.y() == doctest::Approx(3.05));

  // A truncated blob is a clear Corrupt error, not a crash.
  auto truncated = DecodeRtabmapMapBlob(blob.substr(0, 8), 0.0, 0.0, 0.1);
  REQUIRE_FALSE(truncated.ok());
  CHECK(truncated.status().code() == StatusCode::kCorrupt);
  // A database without a saved map says so.
  REQUIRE(sqlite3_open(db_path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db, "UPDATE Admin SET opt_map = NULL", nullptr, nullptr, nullptr) ==
          SQLITE_OK);
  sqlite3_close(db);
  auto empty = LoadOccupancyGrid(db_path);
  REQUIRE_FALSE(empty.ok());
  CHECK(empty.status().code() == StatusCode::kNotFound);
}

TEST_CASE("keyframe-only zones are compact, disjoint and capped in keyframes") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 20.0);
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < 900; ++i) pts.emplace_back(u(rng), u(rng) * 0.5);
  for (int i = 0; i < 300; ++i) pts.emplace_back(3.0 + 0.01 * (i % 10), 3.0);  // a dense spot
  auto zones = ZonesFromKeyframes(pts, {.cell_size_m = 8.0, .max_keyframes = 100, .margin_m = 0.5});
  REQUIRE_MESSAGE(zones.ok(), zones.status().ToString());
  std::vector<int> count(zones->size(), 0);
  for (const auto& p : pts) {
    int inside = 0;
    for (std::size_t z = 0; z < zones->size(); ++z) {
      const auto& ring = (*zones)[z].polygon;
      if (PointInPolygon(ring, p) || DistanceToBoundary(ring, p) < 1e-6) {
        ++count[z];
        ++inside;
      }
    }
    CHECK(inside >= 1);
    CHECK(inside <= 2);  // only points exactly on a shared cut may touch two
  }
  for (std::size_t z = 0; z < zones->size(); ++z) {
    CHECK(count[z] <= 100 + 2);
    CHECK(SignedArea((*zones)[z].polygon) > 0.0);
  }
  CHECK(zones->size() >= 12);

  CHECK_FALSE(ZonesFromKeyframes(pts, {.cell_size_m = 0.0}).ok());
  std::vector<Eigen::Vector2d> same(5, Eigen::Vector2d(1.0, 1.0));
  CHECK_FALSE(ZonesFromKeyframes(same, {.max_keyframes = 2}).ok());
}

TEST_CASE("segments holding too many keyframes are split until each fits") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  auto seg = SegmentRooms(grid, Rules());
  REQUIRE(seg.ok());
  // 60 keyframes along the corridor (y = 6.2 m), 10 in the first room.
  std::vector<Eigen::Vector2d> kf;
  for (int i = 0; i < 60; ++i) kf.emplace_back(1.2 + 0.19 * i, 6.2);
  for (int i = 0; i < 10; ++i) kf.emplace_back(2.0 + 0.2 * i, 3.0);
  const std::size_t before = seg->segments.size();
  REQUIRE(SplitOversizeSegments(grid, kf, 16, &*seg).ok());
  CHECK(seg->segments.size() == before + 3);  // corridor 60 -> 4 parts of 15
  std::map<int, int> per_label;
  for (const auto& p : kf) {
    int col = 0, row = 0;
    REQUIRE(grid.CellOf(p, &col, &row));
    ++per_label[seg->labels.at<int>(row, col)];
  }
  for (const auto& [label, n] : per_label) {
    CHECK(label > 0);
    CHECK(n <= 16);
  }
  CHECK_FALSE(SplitOversizeSegments(grid, kf, 0, &*seg).ok());
}

// Training a model for other cut options starts with an oracle trace cut with them: the oracle
// merges by the ground truth, so the compiled-in model's options do not bind it; a run that
// merges by the model is still refused (issue 28, third round).
// SegmentRooms of `grid` with a trace against `truth` (merged by it with `oracle`), written to a
// file of this test's directory `name`; the trace's text in `*rows`.
Segmentation Traced(const OccupancyGrid& grid, const cv::Mat& truth, const SegmentOptions& o,
                    const LayoutMergeModel& model, bool oracle, const std::string& name,
                    std::string* rows) {
  const auto dir = TempDir(name);
  const std::string csv_path = (dir / "trace.csv").string();
  std::FILE* csv = std::fopen(csv_path.c_str(), "w");
  REQUIRE(csv != nullptr);
  LayoutMergeTrace trace;
  trace.ground_truth = &truth;
  trace.csv = csv;
  trace.oracle = oracle;
  auto seg = SegmentRooms(grid, o, model, trace);
  std::fclose(csv);
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  std::ifstream in(csv_path);
  std::stringstream text;
  text << in.rdbuf();
  *rows = text.str();
  return std::move(seg).value();
}

TEST_CASE("an oracle trace runs with cut options the model was not trained with") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  SegmentOptions other;
  other.cut.layout_cap_max_m = 0.0;  // the compiled-in model has 3.5
  const auto refused = SegmentRooms(grid, other);
  REQUIRE_FALSE(refused.ok());
  CHECK(refused.status().message().find("layout_cap_max_m") != std::string::npos);

  std::string rows;
  const Segmentation traced =
      Traced(grid, truth, other, DefaultLayoutMergeModel(), true, "oracle_other_cut", &rows);
  // The oracle joins the pieces of each room: the three rooms and the corridor.
  CHECK(traced.segments.size() == 4);
  CHECK_FALSE(rows.empty());  // the pairs it saw, with labels
}

TEST_CASE("wall faces: a walled room's are straight, a jagged wall's rough, gaps are unknown") {
  cv::Mat free = cv::Mat::zeros(40, 60, CV_8U), occupied = cv::Mat::zeros(40, 60, CV_8U);
  occupied(cv::Rect(5, 5, 50, 30)).setTo(255);
  free(cv::Rect(6, 6, 48, 28)).setTo(255);
  occupied(cv::Rect(6, 6, 48, 28)).setTo(0);
  const GridFaceShares room = MeasureGridFaces(free, occupied);
  // Only the faces at the four corners' cells do not continue on both sides: 8 of 152.
  CHECK(room.rough == doctest::Approx(8.0 / 152.0));
  CHECK(room.unknown_border == 0.0);
  // Every other cell of the top face a notch: no face continues straight there.
  cv::Mat jagged_free = free.clone(), jagged_occ = occupied.clone();
  for (int c = 7; c < 53; c += 2) {
    jagged_free.at<std::uint8_t>(6, c) = 0;
    jagged_occ.at<std::uint8_t>(6, c) = 255;
  }
  CHECK(MeasureGridFaces(jagged_free, jagged_occ).rough > 0.3);
  // A 10-cell gap in the bottom wall, unknown beyond (neither free nor occupied).
  occupied(cv::Rect(20, 34, 10, 1)).setTo(0);
  CHECK(MeasureGridFaces(free, occupied).unknown_border == doctest::Approx(10.0 / 152.0));
}

TEST_CASE("a rough grid's layout pieces are cut with the rough-grid options, a clean one's not") {
  // The wardrobe floor: two 0.7 m side walls with free ends, which the layout cut caps across
  // and continues past their corners (issue 16, sixth part).
  const Floor f = WardrobeFloor();
  const double share = GridRoughFaceShare(f.grid);
  CHECK(share > 0.0);
  CHECK(share < 0.2);  // a drawn plan: straight faces but at corners and wall ends

  // The default: no grid is rough.
  const SegmentOptions clean;
  auto seg = SegmentRooms(f.grid, clean, NeverMerges(clean));
  REQUIRE_MESSAGE(seg.ok(), seg.status().ToString());
  CHECK_FALSE(seg->rough_cut);
  CHECK(seg->rough_face_share == share);

  // Rough from just below this grid's share: the rough-grid lengths replace corners and caps.
  SegmentOptions rough;
  rough.cut.layout_rough_face_share = share - 1e-6;
  rough.cut.layout_rough_corner_max_m = 0.0;
  rough.cut.layout_rough_cap_max_m = 0.0;
  auto rough_seg = SegmentRooms(f.grid, rough, NeverMerges(rough));
  REQUIRE_MESSAGE(rough_seg.ok(), rough_seg.status().ToString());
  CHECK(rough_seg->rough_cut);
  SegmentOptions without;  // the same pieces as corners and caps turned off outright
  without.cut.layout_corner_max_m = 0.0;
  without.cut.layout_cap_max_m = 0.0;
  auto without_seg = SegmentRooms(f.grid, without, NeverMerges(without));
  REQUIRE(without_seg.ok());
  CHECK(cv::countNonZero(rough_seg->labels != without_seg->labels) == 0);
  CHECK(seg->segments.size() > rough_seg->segments.size());  // the caps' and corners' pieces

  // At exactly its share the grid is not rough (rough means above), and the rule merges never
  // use the layout cut.
  rough.cut.layout_rough_face_share = share;
  auto at = SegmentRooms(f.grid, rough, NeverMerges(rough));
  REQUIRE(at.ok());
  CHECK_FALSE(at->rough_cut);
  CHECK(cv::countNonZero(at->labels != seg->labels) == 0);
  SegmentOptions rules = Rules();
  rules.cut.layout_rough_face_share = 0.0;
  auto by_rules = SegmentRooms(f.grid, rules);
  REQUIRE(by_rules.ok());
  CHECK_FALSE(by_rules->rough_cut);

  // The model is told which cut ran: map_rough_cut, a feature of every trace row (its column
  // found by name: the step and the label come first).
  std::size_t column = 2;
  while (std::string(kLayoutFeatureNames[column - 2]) != "map_rough_cut") ++column;
  rough.cut.layout_rough_face_share = 0.0;
  for (const bool is_rough : {false, true}) {
    const SegmentOptions& o = is_rough ? rough : clean;
    std::string rows;
    Traced(f.grid, f.truth, o, NeverMerges(o), false, is_rough ? "rough_cut" : "clean_cut",
           &rows);
    std::stringstream row(rows.substr(0, rows.find('\n')));
    std::vector<std::string> fields;
    for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
    REQUIRE(fields.size() == 2 + kLayoutFeatureNames.size());
    CHECK(fields[column] == (is_rough ? "1" : "0"));
  }
}

TEST_CASE("a cropped grid's trace is labelled from its own cells of the ground truth") {
  // The floor inside 30 m of unknown on every side: only the known part (plus a 10 m rim) is
  // segmented, and the ground truth must be read at the same cells.
  cv::Mat truth;
  const OccupancyGrid floor = SyntheticFloor(&truth);
  constexpr int kPad = 600;  // 30 m at 0.05 m
  OccupancyGrid padded = floor;
  cv::copyMakeBorder(floor.cells, padded.cells, kPad, kPad, kPad, kPad, cv::BORDER_CONSTANT,
                     cv::Scalar(kCellUnknown));
  cv::Mat padded_truth;
  cv::copyMakeBorder(truth, padded_truth, kPad, kPad, kPad, kPad, cv::BORDER_CONSTANT,
                     cv::Scalar(0));
  std::string plain, cropped;
  Traced(floor, truth, SegmentOptions{}, DefaultLayoutMergeModel(), true, "trace_plain", &plain);
  Traced(padded, padded_truth, SegmentOptions{}, DefaultLayoutMergeModel(), true, "trace_cropped",
         &cropped);
  CHECK_FALSE(plain.empty());
  CHECK(cropped == plain);
  // Labelled at all: some pair is one room (the oracle joins each room's pieces).
  CHECK(plain.find(",1,") != std::string::npos);
}

TEST_CASE("rough-grid options out of range are one clear error") {
  cv::Mat truth;
  const OccupancyGrid grid = SyntheticFloor(&truth);
  SegmentOptions o;
  o.cut.layout_rough_face_share = 1.5;
  auto r = SegmentRooms(grid, o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("layout_rough_face_share is a share of wall faces: it must be "
                                  "in [0, 1], got 1.5") != std::string::npos);
  o.cut.layout_rough_face_share = 0.5;
  o.cut.layout_rough_cap_max_m = -1.0;
  r = SegmentRooms(grid, o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("layout_* lengths and areas must be >= 0") !=
        std::string::npos);
  o.cut.layout_rough_cap_max_m = 1.0;
  o.learned.layout_corridor_border_ratio = -0.5;
  r = SegmentRooms(grid, o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("layout_corridor_border_ratio must be >= 0, got -0.5") !=
        std::string::npos);
  o.learned.layout_corridor_border_ratio = 0.0;
  o.learned.layout_channel_depth_m = -1.0;
  r = SegmentRooms(grid, o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("layout_channel_depth_m must be >= 0, got -1") !=
        std::string::npos);
  o.learned.layout_channel_depth_m = 0.0;
  o.learned.layout_channel_before_model = 0.5;
  r = SegmentRooms(grid, o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("layout_channel_before_model must be 0 (after the model) or 1 "
                                  "(before it), got 0.5") != std::string::npos);
}


}  // namespace
}  // namespace zm
