// The learned layout merge: model parsing (one clear error per defect), the ensemble's
// arithmetic, greedy merging of layout pieces by a model, the training trace's labels and the
// oracle's merges, the border-kind features, and the compiled-in model.
#include "segment/layout_merge.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "segment/declutter.h"

namespace zm {
namespace {

std::string Names() {
  std::string s = "[";
  for (int i = 0; i < kLayoutFeatureCount; ++i) {
    s += std::string(i ? "," : "") + "\"" + kLayoutFeatureNames[static_cast<std::size_t>(i)] + "\"";
  }
  return s + "]";
}

// One stump on open_fraction: below `split` the pair is two rooms (p ~ 0), above it one (p ~ 1).
std::string StumpModel(double split) {
  return "{\"features\":" + Names() +
         ",\"init\":0,\"learning_rate\":1,\"trees\":[{\"feature\":[2,-1,-1],\"threshold\":[" +
         std::to_string(split) +
         ",0,0],\"left\":[1,-1,-1],\"right\":[2,-1,-1],\"value\":[0,-10,10]}],"
         "\"trained_with\":" +
         LayoutMergeTrainedWithJson(CutOptions{}, RuleMergeOptions{}) + "}";
}

// Room A (columns 0-99) cut in two pieces by a line through free space (pieces 1 and 2), a wall
// three cells thick at columns 100-102 with a 0.9 m door (rows 40-57), room B (piece 3) beyond.
struct Scene {
  cv::Mat labels = cv::Mat::zeros(100, 200, CV_32S);
  cv::Mat occupied = cv::Mat::zeros(100, 200, CV_8U);
  cv::Mat gt = cv::Mat::zeros(100, 200, CV_32S);
  Scene() {
    cv::rectangle(occupied, cv::Rect(0, 0, 200, 100), cv::Scalar(255), 1);
    labels(cv::Rect(1, 1, 49, 98)).setTo(1);
    labels(cv::Rect(50, 1, 50, 98)).setTo(2);
    occupied(cv::Rect(100, 1, 3, 98)).setTo(255);
    occupied(cv::Rect(100, 40, 3, 18)).setTo(0);
    labels(cv::Rect(100, 40, 3, 18)).setTo(3);
    labels(cv::Rect(103, 1, 96, 98)).setTo(3);
    gt(cv::Rect(1, 1, 99, 98)).setTo(7);
    gt(cv::Rect(100, 1, 99, 98)).setTo(9);
    gt(cv::Rect(100, 40, 3, 18)).setTo(9);
  }
  LayoutMergeInputs Inputs() {
    LayoutMergeInputs in;
    in.labels = &labels;
    in.count = 3;
    in.occupied = occupied;
    in.resolution_m = 0.05;
    return in;
  }
};

// Runs the merge of `in` with a trace against `gt` (the oracle's merges when `oracle`); returns
// the trace's CSV lines and the merge's result in `*merged`.
std::vector<std::string> TraceLines(const LayoutMergeInputs& in, const cv::Mat& gt, bool oracle,
                                    double threshold, Result<int>* merged) {
  const cv::Mat truth = gt.clone();
  std::FILE* csv = std::tmpfile();
  REQUIRE(csv != nullptr);
  LayoutMergeTrace trace;
  trace.ground_truth = &truth;
  trace.csv = csv;
  trace.oracle = oracle;
  *merged = MergeLayoutPieces(in, LayoutMergeModel{}, threshold, trace);  // the oracle or p 0.5
  std::rewind(csv);
  std::vector<std::string> lines;
  char line[4096];
  while (std::fgets(line, sizeof line, csv) != nullptr) lines.emplace_back(line);
  std::fclose(csv);
  return lines;
}

TEST_CASE("a layout merge model parses, and each defect gets one clear error") {
  auto ok = ParseLayoutMergeModel(StumpModel(0.8));
  REQUIRE(ok.ok());
  CHECK(ok->trees.size() == 1);
  CHECK(ok->Uses(2));  // its one split, on open_fraction
  CHECK_FALSE(ok->Uses(kLayoutFeatureCount - 2));  // so no line of sight is traced for it

  std::string wrong_name = StumpModel(0.8);
  wrong_name.replace(wrong_name.find("wall_m"), 6, "wall_x");
  auto bad = ParseLayoutMergeModel(wrong_name);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("feature 1 is 'wall_x'") != std::string::npos);

  // A model of an earlier version lists the first features only (backward compatible), and
  // its trees may use no other; more names than zonemap knows are refused.
  const std::string record =
      ",\"trained_with\":" + LayoutMergeTrainedWithJson(CutOptions{}, RuleMergeOptions{}) + "}";
  const std::string prefix =
      "{\"features\":[\"open_m\",\"wall_m\",\"open_fraction\"],\"init\":0,"
      "\"learning_rate\":1,\"trees\":[{\"feature\":[2,-1,-1],\"threshold\":[0.8,0,0],"
      "\"left\":[1,-1,-1],\"right\":[2,-1,-1],\"value\":[0,-10,10]}]";
  CHECK(ParseLayoutMergeModel(prefix + record).ok());
  std::string beyond = prefix;
  beyond.replace(beyond.find("\"feature\":[2"), 12, "\"feature\":[3");
  auto uses_unlisted = ParseLayoutMergeModel(beyond + record);
  REQUIRE_FALSE(uses_unlisted.ok());
  CHECK(uses_unlisted.status().message().find("node 0 is malformed") != std::string::npos);
  std::string names = Names();
  names.insert(names.size() - 1, ",\"map_future\"");
  auto too_many = ParseLayoutMergeModel("{\"features\":" + names +
                                        ",\"init\":0,\"learning_rate\":1,\"trees\":[]" + record);
  REQUIRE_FALSE(too_many.ok());
  CHECK(too_many.status().message().find(std::to_string(kLayoutFeatureCount + 1) +
                                         " features, expected 1 to " +
                                         std::to_string(kLayoutFeatureCount)) != std::string::npos);
  auto no_names = ParseLayoutMergeModel(
      "{\"features\":[],\"init\":0,\"learning_rate\":1,"
      "\"trees\":[]" +
      record);
  REQUIRE_FALSE(no_names.ok());

  std::string cycle = StumpModel(0.8);
  cycle.replace(cycle.find("\"left\":[1"), 9, "\"left\":[0");
  auto cyclic = ParseLayoutMergeModel(cycle);
  REQUIRE_FALSE(cyclic.ok());
  CHECK(cyclic.status().message().find("node 0 is malformed") != std::string::npos);

  auto lengths = ParseLayoutMergeModel("{\"features\":" + Names() +
                                       ",\"init\":0,\"learning_rate\":1,\"trees\":[{\"feature\":"
                                       "[-1],\"threshold\":[0],\"left\":[-1],\"right\":[],"
                                       "\"value\":[1]}]}");
  REQUIRE_FALSE(lengths.ok());
  CHECK(lengths.status().message().find("different lengths") != std::string::npos);

  CHECK_FALSE(ParseLayoutMergeModel("not json").ok());
  CHECK_FALSE(LoadLayoutMergeModel("/nonexistent/model.json").ok());
}

TEST_CASE("a model records the options its pieces were cut with, and refuses others") {
  auto m = ParseLayoutMergeModel(StumpModel(0.8));
  REQUIRE(m.ok());
  CHECK(CheckLayoutMergeModelOptions(*m, CutOptions{}, RuleMergeOptions{}).ok());
  CutOptions narrow_doors;
  narrow_doors.door_max_width_m = 0.9;
  const Status cut = CheckLayoutMergeModelOptions(*m, narrow_doors, RuleMergeOptions{});
  CHECK(cut.code() == StatusCode::kInvalidArgument);
  CHECK(cut.message().find("door_max_width_m=1.2, these options have 0.9") != std::string::npos);
  RuleMergeOptions rules;
  rules.min_room_area_m2 = 1.0;
  CHECK(CheckLayoutMergeModelOptions(*m, CutOptions{}, rules)
            .message()
            .find("min_room_area_m2=0.5") != std::string::npos);

  std::string none = StumpModel(0.8);
  none.erase(none.find(",\"trained_with\""));
  auto missing = ParseLayoutMergeModel(none + "}");
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().message().find("no \"trained_with\"") != std::string::npos);
  std::string extra = StumpModel(0.8);
  extra.replace(extra.find("\"door_max_width_m\""), 18, "\"door_width_m\"");
  auto unknown = ParseLayoutMergeModel(extra);
  REQUIRE_FALSE(unknown.ok());
  CHECK(unknown.status().message().find("trained_with.cut: unknown option 'door_width_m'") !=
        std::string::npos);

  // The compiled-in model was trained with the defaults (docs/segmentation.md).
  CHECK(CheckLayoutMergeModelOptions(DefaultLayoutMergeModel(), CutOptions{}, RuleMergeOptions{})
            .ok());
}

TEST_CASE("the ensemble is sigmoid(init + rate x leaf values), left at x <= threshold") {
  auto m = ParseLayoutMergeModel(StumpModel(0.5));
  REQUIRE(m.ok());
  std::array<float, kLayoutFeatureCount> x{};
  x[2] = 0.5f;  // at the threshold: left
  CHECK(m->Probability(x) == doctest::Approx(1.0 / (1.0 + std::exp(10.0))));
  x[2] = 0.51f;
  CHECK(m->Probability(x) == doctest::Approx(1.0 / (1.0 + std::exp(-10.0))));
  const LayoutMergeModel empty;
  CHECK(empty.Probability(x) == doctest::Approx(0.5));
}

TEST_CASE("pieces of one room merge across an open line, not through a door in a wall") {
  Scene s;
  auto model = ParseLayoutMergeModel(StumpModel(0.8));
  REQUIRE(model.ok());
  auto merged = MergeLayoutPieces(s.Inputs(), *model, 0.5);
  REQUIRE(merged.ok());
  CHECK(*merged == 2);
  CHECK(s.labels.at<int>(50, 10) == s.labels.at<int>(50, 90));
  CHECK(s.labels.at<int>(50, 10) != s.labels.at<int>(50, 150));
  CHECK(s.labels.at<int>(50, 101) == s.labels.at<int>(50, 150));  // the door stays with B
  CHECK(s.labels.at<int>(0, 0) == 0);

  // A threshold no pair reaches merges nothing; pieces keep dense labels.
  Scene t;
  auto none = MergeLayoutPieces(t.Inputs(), *model, 1.0);
  REQUIRE(none.ok());
  CHECK(*none == 3);
}

TEST_CASE("the trace labels every pair by the ground truth and the oracle merges by it") {
  Scene s;
  Result<int> merged = 0;
  const std::vector<std::string> lines = TraceLines(s.Inputs(), s.gt, true, 0.5, &merged);
  REQUIRE(merged.ok());
  CHECK(*merged == 2);
  CHECK(s.labels.at<int>(50, 10) == s.labels.at<int>(50, 90));
  CHECK(s.labels.at<int>(50, 10) != s.labels.at<int>(50, 150));
  std::set<std::string> step0;
  int fields = 0;
  for (const std::string& l : lines) {
    if (l.rfind("0,", 0) == 0) step0.insert(l.substr(0, 4));
    fields = 1;
    for (char ch : l) fields += ch == ',';
  }
  CHECK(lines.size() == 3);  // two pairs at step 0, one (A with B) at step 1
  CHECK(step0 == std::set<std::string>{"0,0,", "0,1,"});  // one pair of one room, one not
  CHECK(fields == 2 + kLayoutFeatureCount);
}

TEST_CASE("the border's doorway and opening-kind shares are features") {
  Scene s;
  LayoutMergeInputs in = s.Inputs();
  in.doorways = cv::Mat::zeros(s.labels.size(), CV_8U);
  in.doorways(cv::Rect(100, 40, 3, 18)).setTo(255);  // the door between A and B
  in.opening_kinds = cv::Mat::zeros(s.labels.size(), CV_8U);
  in.opening_kinds(cv::Rect(49, 1, 2, 98)).setTo(kOpeningCap);  // the line cutting A
  Result<int> merged = 0;
  std::map<int, std::vector<double>> by_label;  // 1: the pair within A, 0: A's piece and B
  for (const std::string& line : TraceLines(in, s.gt, false, 0.99, &merged)) {  // no merge
    std::vector<double> v;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) v.push_back(std::stod(field));
    by_label[static_cast<int>(v[1])] = std::vector<double>(v.begin() + 2, v.end());
  }
  REQUIRE(merged.ok());
  REQUIRE(by_label.size() == 2);
  auto feature = [&](int label, const std::string& name) {
    for (int i = 0; i < kLayoutFeatureCount; ++i) {
      if (name == kLayoutFeatureNames[static_cast<std::size_t>(i)]) {
        return by_label[label][static_cast<std::size_t>(i)];
      }
    }
    FAIL("no feature " << name);
    return -1.0;
  };
  CHECK(feature(1, "cap_share") == doctest::Approx(1.0));
  CHECK(feature(1, "doorway_share") == doctest::Approx(0.0));
  CHECK(feature(0, "doorway_share") == doctest::Approx(1.0));
  CHECK(feature(0, "cap_share") == doctest::Approx(0.0));
  for (const char* name : {"free_end_share", "corner_share", "mouth_share", "facade_share"}) {
    CHECK(feature(0, name) == 0.0);
    CHECK(feature(1, name) == 0.0);
  }
  // The channel widths: room A cut across its whole width keeps the border's width on both
  // sides (1, as a corridor cut across would); past the 0.9 m door both rooms are far wider
  // (the cap, 4).
  CHECK(feature(1, "channel_width_near") == doctest::Approx(1.0).epsilon(0.02));
  CHECK(feature(1, "channel_width_far") == doctest::Approx(1.0).epsilon(0.02));
  CHECK(feature(0, "channel_width_near") == doctest::Approx(4.0));
  CHECK(feature(0, "channel_width_far") == doctest::Approx(4.0));
  // Of the wrong type: one clear error.
  in.doorways = cv::Mat::zeros(s.labels.size(), CV_32S);
  auto bad = MergeLayoutPieces(in, LayoutMergeModel{}, 0.99);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("doorways and opening kinds") != std::string::npos);
}

// The features of the first pair row of a trace, by name.
std::map<std::string, double> FirstRowFeatures(const LayoutMergeInputs& in, const cv::Mat& gt) {
  Result<int> merged = 0;
  const std::vector<std::string> lines = TraceLines(in, gt, false, 0.99, &merged);
  REQUIRE(merged.ok());
  REQUIRE_FALSE(lines.empty());
  std::vector<double> v;
  std::stringstream ss(lines.front());
  std::string field;
  while (std::getline(ss, field, ',')) v.push_back(std::stod(field));
  REQUIRE(v.size() == 2 + kLayoutFeatureCount);
  std::map<std::string, double> out;
  for (int i = 0; i < kLayoutFeatureCount; ++i) {
    out[kLayoutFeatureNames[static_cast<std::size_t>(i)]] = v[static_cast<std::size_t>(2 + i)];
  }
  return out;
}

TEST_CASE("map-level features tell a clean grid from a noisy one") {
  Scene clean;
  const auto a = FirstRowFeatures(clean.Inputs(), clean.gt);
  CHECK(a.at("map_specks_per_100m2") == 0.0);
  CHECK(a.at("map_blobs_per_100m2") == 0.0);
  CHECK(a.at("map_loose_occupied_share") == 0.0);
  CHECK(a.at("map_unknown_border_share") == 0.0);  // walled all round
  CHECK(a.at("map_rough_face_share") < 0.05);      // only the corners and the door's jambs

  // The same rooms with a robot's defects: two one-cell specks and a 0.5 m blob of clutter in
  // room B, a gap of 1 m in the outer wall (unknown beyond), a notch in a wall face.
  Scene noisy;
  for (const cv::Point p : {cv::Point(150, 20), cv::Point(170, 80)}) {
    noisy.occupied.at<std::uint8_t>(p) = 255;
    noisy.labels.at<int>(p) = 0;
  }
  noisy.occupied(cv::Rect(130, 50, 10, 4)).setTo(255);
  noisy.labels(cv::Rect(130, 50, 10, 4)).setTo(0);
  noisy.occupied(cv::Rect(160, 99, 20, 1)).setTo(0);  // the gap: neither occupied nor a piece
  noisy.occupied.at<std::uint8_t>(50, 1) = 255;       // the notch, on A's left wall
  noisy.labels.at<int>(50, 1) = 0;
  const auto b = FirstRowFeatures(noisy.Inputs(), noisy.gt);
  const double free_m2 = b.at("map_free_m2");
  CHECK(b.at("map_specks_per_100m2") == doctest::Approx(2 * 100.0 / free_m2));
  CHECK(b.at("map_blobs_per_100m2") == doctest::Approx(100.0 / free_m2));
  CHECK(b.at("map_loose_occupied_share") > 0.0);
  CHECK(b.at("map_unknown_border_share") > 0.0);
  CHECK(b.at("map_rough_face_share") > a.at("map_rough_face_share"));

  // Which cut made the pieces is the caller's to say (SegmentRooms: CutOptions::layout_rough_*).
  CHECK(a.at("map_rough_cut") == 0.0);
  LayoutMergeInputs rough = clean.Inputs();
  rough.rough_cut = true;
  CHECK(FirstRowFeatures(rough, clean.gt).at("map_rough_cut") == 1.0);
}

TEST_CASE("a border's end extents tell a door's jambs from a gap beside furniture") {
  // A door in a wall: both ends of the border are the inner wall, one component with the outer
  // one (10 m across): the cap on both sides.
  Scene door;
  LayoutMergeInputs in = door.Inputs();
  in.labels->setTo(0);
  in.labels->operator()(cv::Rect(80, 40, 20, 18)).setTo(1);   // in front of the door, in A
  in.labels->operator()(cv::Rect(100, 40, 23, 18)).setTo(2);  // the door and beyond, in B
  in.count = 2;
  const auto d = FirstRowFeatures(in, door.gt);
  CHECK(d.at("end_extent_min_m") == doctest::Approx(8.0));
  CHECK(d.at("end_extent_max_m") == doctest::Approx(8.0));
  CHECK(d.at("end_support_min") == doctest::Approx(1.0));

  // Two pieces of one room that touch through a 1.45 m gap between the outer wall and a
  // free-standing table (1.0 x 0.5 m): one end is the wall, the other the table.
  Scene room;
  cv::Mat labels = cv::Mat::zeros(100, 200, CV_32S);
  labels(cv::Rect(30, 1, 20, 29)).setTo(1);
  labels(cv::Rect(50, 1, 20, 29)).setTo(2);
  room.occupied(cv::Rect(45, 30, 10, 20)).setTo(255);  // the table, below the gap
  LayoutMergeInputs gap = room.Inputs();
  gap.labels = &labels;
  gap.count = 2;
  const auto g = FirstRowFeatures(gap, room.gt);
  CHECK(g.at("end_extent_min_m") == doctest::Approx(1.0));  // the table's 20 cells
  CHECK(g.at("end_extent_max_m") == doctest::Approx(8.0));  // the outer wall, capped

  // Nothing occupied within 0.4 m beyond an end: 0 there.
  room.occupied(cv::Rect(45, 30, 10, 20)).setTo(0);
  const auto open = FirstRowFeatures(gap, room.gt);
  CHECK(open.at("end_extent_min_m") == 0.0);
  CHECK(open.at("end_extent_max_m") == doctest::Approx(8.0));
}

// The first trace row of each label (1: the two pieces are one room, 0: not), by feature name.
std::map<int, std::map<std::string, double>> RowsByLabel(const LayoutMergeInputs& in,
                                                         const cv::Mat& gt) {
  Result<int> merged = 0;
  std::map<int, std::map<std::string, double>> rows;
  for (const std::string& line : TraceLines(in, gt, false, 0.99, &merged)) {  // no merge
    std::vector<double> v;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) v.push_back(std::stod(field));
    REQUIRE(v.size() == 2 + kLayoutFeatureCount);
    auto& row = rows[static_cast<int>(v[1])];
    if (!row.empty()) continue;
    for (int i = 0; i < kLayoutFeatureCount; ++i) {
      row[kLayoutFeatureNames[static_cast<std::size_t>(i)]] = v[static_cast<std::size_t>(2 + i)];
    }
  }
  REQUIRE(merged.ok());
  return rows;
}

TEST_CASE("two pieces of one room see each other, past clutter; two rooms only through a door") {
  Scene s;
  auto rows = RowsByLabel(s.Inputs(), s.gt);
  REQUIRE(rows.size() == 2);
  // Room A's two halves: every sample of one sees every sample of the other.
  CHECK(rows[1].at("visibility") == doctest::Approx(1.0));
  CHECK(rows[1].at("visibility_s") == doctest::Approx(1.0));
  // A's right half and room B: only lines through the 0.9 m door, about a quarter.
  CHECK(rows[0].at("visibility") > 0.0);
  CHECK(rows[0].at("visibility") < 0.35);
  CHECK(rows[0].at("visibility_s") < rows[1].at("visibility_s"));

  // A table (1.0 x 0.5 m, occupied, no piece) on the line between A's halves: a robot sees past
  // it, so the halves still see each other wholly...
  Scene table;
  table.occupied(cv::Rect(40, 45, 20, 10)).setTo(255);
  table.labels(cv::Rect(40, 45, 20, 10)).setTo(0);
  CHECK(RowsByLabel(table.Inputs(), table.gt)[1].at("visibility") == doctest::Approx(1.0));
  // ...but a wall 3 m long (longer than any clutter, 1.5 m) hides part of each from the other.
  Scene wall;
  wall.occupied(cv::Rect(48, 20, 4, 60)).setTo(255);
  wall.labels(cv::Rect(48, 20, 4, 60)).setTo(0);
  const double behind = RowsByLabel(wall.Inputs(), wall.gt)[1].at("visibility");
  CHECK(behind > 0.0);
  CHECK(behind < 0.8);

  // Unknown cells (neither free, occupied nor a piece) block a line of sight like a wall.
  Scene unknown;
  LayoutMergeInputs in = unknown.Inputs();
  unknown.labels(cv::Rect(48, 20, 4, 60)).setTo(0);
  in.free = unknown.labels > 0;
  CHECK(RowsByLabel(in, unknown.gt)[1].at("visibility") == doctest::Approx(behind));
}

TEST_CASE("bad inputs to the layout merge are one clear error") {
  Scene s;
  LayoutMergeInputs in = s.Inputs();
  cv::Mat wrong = cv::Mat::zeros(10, 10, CV_8U);
  in.occupied = wrong;
  auto r = MergeLayoutPieces(in, LayoutMergeModel{}, 0.5);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("same size") != std::string::npos);
}

TEST_CASE("the compiled-in model parses and has trees") {
  CHECK(DefaultLayoutMergeModel().trees.size() >= 10);
}

}  // namespace
}  // namespace zm
