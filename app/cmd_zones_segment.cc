// `zonemap zones segment`: automatic semantic zones. From an occupancy grid (ROS YAML, PNG
// floor plan, or an RTAB-Map database's Admin.opt_map) by room segmentation, or from the map
// database's keyframes alone when no grid is given. Writes a GeoJSON zone file; optionally caps
// the keyframes per zone (--db with --max-zone-keyframes) and scores against a ground-truth PNG.
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "commands.h"
#include "mapdb/map_db.h"
#include "segment/grid_map.h"
#include "segment/score.h"
#include "segment/segmentation.h"
#include "segment/split.h"
#include "segment/write.h"

namespace zm::app {
namespace {

struct SegmentOpts {
  std::string map;
  std::string out;
  std::string score_gt;
  std::string db;
  int max_zone_keyframes = 0;
  double resolution_m = 0.0;
  double cell_size_m = 8.0;
  std::vector<std::string> params;  // KEY=VALUE overrides of SegmentOptions (SetSegmentParam)
  std::string labels_png;
  std::string merge_model;    // a layout merge model JSON instead of the compiled-in one
  std::string merge_trace;    // CSV of every pair's features and --score's label, every step
  bool merge_oracle = false;  // trace: merge by the ground truth instead of the model
  bool json = false;
};

// Sets `field` of `stage` when `key` names it in `fields`; true when it did.
template <class Options, std::size_t N>
bool SetField(const OptionField<Options> (&fields)[N], const std::string& key, double value,
              Options* stage, std::string* known) {
  for (const OptionField<Options>& f : fields) {
    if (key == f.name) {
      stage->*f.field = value;
      return true;
    }
    *known += (known->empty() ? "" : ", ") + std::string(f.name);
  }
  return false;
}

// `--param KEY=VALUE`: KEY is an option's name in its stage's table (segment/cut.h, merge.h,
// write.h), VALUE a number in the option's unit. An unknown key or a value that is not a finite
// number is an InvalidArgument naming it, and so is a value out of its range. For evaluation
// runs (leave-one-out parameter choice); the defaults are the product.
Status SetSegmentParam(const std::string& key_value, SegmentOptions* options) {
  const auto eq = key_value.find('=');
  if (eq == std::string::npos) {
    return InvalidArgument("segmentation option '" + key_value + "': expected KEY=VALUE");
  }
  const std::string key = key_value.substr(0, eq);
  const std::string text = key_value.substr(eq + 1);
  double value = 0.0;
  try {
    std::size_t used = 0;
    value = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(value)) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    return InvalidArgument("segmentation option '" + key + "': '" + text + "' is not a number");
  }
  std::string known;
  if (SetField(kCutOptionFields, key, value, &options->cut, &known) ||
      SetField(kRuleMergeOptionFields, key, value, &options->rules, &known) ||
      SetField(kKindOptionFields, key, value, &options->kinds, &known) ||
      SetField(kOutlineOptionFields, key, value, &options->outline, &known) ||
      SetField(kLearnedMergeOptionFields, key, value, &options->learned, &known)) {
    return CheckSegmentOptions(*options);
  }
  return InvalidArgument("unknown segmentation option '" + key + "' (known: " + known + ")");
}

// Room segmentation allocates and frees a few dozen image buffers of the grid's size per stage.
// glibc gives buffers above its mmap threshold fresh pages each time and trims freed heap tops
// back to the kernel, so every stage paid its buffers' page faults again: a third of the
// command's CPU time on map17 (docs/segmentation.md, "Runtime"). This short offline process keeps
// its freed memory for reuse instead: buffers up to 32 MB (glibc's largest threshold; a grid of
// 8 million cells' CV_32S image) come from the heap, and the heap is not trimmed. The peak grows
// by a few MB.
void KeepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
}

Result<std::vector<Eigen::Vector2d>> KeyframePositions(const std::string& db_path) {
  ZM_ASSIGN_OR_RETURN(auto db, MapDb::Open(db_path));
  ZM_ASSIGN_OR_RETURN(auto keyframes, db->Keyframes());
  std::vector<Eigen::Vector2d> positions;
  positions.reserve(keyframes.size());
  for (const KeyframeMeta& k : keyframes) positions.push_back(k.pose.translation().head<2>());
  return positions;
}

void Run(const SegmentOpts& o, CommandContext& ctx) {
  constexpr const char* kCmd = "zones segment";
  KeepFreedMemory();
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Eigen::Vector2d> keyframes;
  if (!o.db.empty()) {
    auto positions = KeyframePositions(o.db);
    if (!positions.ok()) return ctx.Fail(kCmd, positions.status());
    keyframes = std::move(positions).value();
  }
  if (o.max_zone_keyframes < 0) {
    return ctx.Fail(kCmd, "--max-zone-keyframes must be >= 0 (0 = no cap)");
  }
  nlohmann::json report;
  std::vector<Zone> zones;
  if (o.map.empty()) {
    // No grid: compact zones from the keyframe positions alone.
    if (o.db.empty()) return ctx.Fail(kCmd, "give MAP (.yaml, .png or RTAB-Map .db) or --db");
    if (!o.score_gt.empty()) return ctx.Fail(kCmd, "--score needs an occupancy grid MAP");
    KeyframeZoneOptions kz;
    kz.cell_size_m = o.cell_size_m;
    kz.max_keyframes = o.max_zone_keyframes > 0 ? o.max_zone_keyframes : kz.max_keyframes;
    auto made = ZonesFromKeyframes(keyframes, kz);
    if (!made.ok()) return ctx.Fail(kCmd, made.status());
    zones = std::move(made).value();
    report["source"] = "keyframes";
    report["keyframes"] = keyframes.size();
  } else {
    // The options first: a mistyped --param fails before any map is read.
    SegmentOptions options;
    for (const std::string& kv : o.params) {
      if (Status st = SetSegmentParam(kv, &options); !st.ok()) return ctx.Fail(kCmd, st);
    }
    auto grid = LoadOccupancyGrid(o.map, o.resolution_m);
    if (!grid.ok()) return ctx.Fail(kCmd, grid.status());
    LayoutMergeModel model = DefaultLayoutMergeModel();
    if (!o.merge_model.empty()) {
      auto loaded = LoadLayoutMergeModel(o.merge_model);
      if (!loaded.ok()) return ctx.Fail(kCmd, loaded.status());
      model = std::move(loaded).value();
    }
    // Training data for the layout merge (scripts/train_layout_merge.py): the ground truth
    // labels each pair at each step.
    cv::Mat trace_gt;
    LayoutMergeTrace trace;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> trace_file(nullptr, &std::fclose);
    if (!o.merge_trace.empty()) {
      if (o.score_gt.empty()) return ctx.Fail(kCmd, "--merge-trace needs --score GT.png");
      auto gt = LoadGroundTruthLabels(o.score_gt);
      if (!gt.ok()) return ctx.Fail(kCmd, gt.status());
      trace_gt = std::move(gt).value();
      trace_file.reset(std::fopen(o.merge_trace.c_str(), "w"));
      if (!trace_file) return ctx.Fail(kCmd, o.merge_trace + ": cannot open for writing");
      trace.ground_truth = &trace_gt;
      trace.csv = trace_file.get();
      trace.oracle = o.merge_oracle;
      // What a model trained on this trace records (scripts/train_layout_merge.py reads it).
      report["trained_with"] =
          nlohmann::json::parse(LayoutMergeTrainedWithJson(options.cut, options.rules));
    } else if (o.merge_oracle) {
      return ctx.Fail(kCmd, "--merge-oracle needs --merge-trace");
    }
    auto seg = SegmentRooms(*grid, options, model, trace);
    if (!seg.ok()) return ctx.Fail(kCmd, o.map + ": " + seg.status().message());
    report["source"] = o.map;
    report["segment_ms"] = seg->runtime_ms;
    // Which layout cut ran: a robot's rough grid is cut with CutOptions::layout_rough_*.
    report["rough_face_share"] = seg->rough_face_share;
    report["rough_cut"] = seg->rough_cut;
    if (!o.labels_png.empty()) {
      if (Status st = WriteSegmentationPng(o.labels_png, *grid, *seg); !st.ok()) {
        return ctx.Fail(kCmd, st);
      }
    }
    if (!o.score_gt.empty()) {
      auto gt = LoadGroundTruthLabels(o.score_gt);
      if (!gt.ok()) return ctx.Fail(kCmd, gt.status());
      if (std::abs(gt->rows - grid->rows()) > 1 || std::abs(gt->cols - grid->cols()) > 1) {
        return ctx.Fail(kCmd, o.score_gt + ": ground truth is " + std::to_string(gt->cols) + "x" +
                                  std::to_string(gt->rows) + ", map is " +
                                  std::to_string(grid->cols()) + "x" +
                                  std::to_string(grid->rows()) + " (at most 1 pixel apart)");
      }
      const cv::Mat free_cells = grid->cells == kCellFree;
      auto score = ScoreSegmentation(seg->labels, *gt, free_cells);
      if (!score.ok()) return ctx.Fail(kCmd, score.status());
      report["score"] = {{"precision", score->precision},
                         {"recall", score->recall},
                         {"mean_iou", score->mean_iou},
                         {"mean_iou_full", score->mean_iou_full},
                         {"mean_iou_shown", score->mean_iou_shown},
                         {"gt_rooms", score->gt_rooms},
                         {"gt_rooms_shown", score->gt_rooms_shown},
                         {"segments", score->predicted_segments}};
    }
    if (o.max_zone_keyframes > 0) {
      if (o.db.empty()) return ctx.Fail(kCmd, "--max-zone-keyframes needs --db MAP.db");
      const std::size_t before = seg->segments.size();
      Status split = SplitOversizeSegments(*grid, keyframes, o.max_zone_keyframes, &*seg);
      if (!split.ok()) return ctx.Fail(kCmd, split);
      report["split_added"] = seg->segments.size() - before;
    }
    auto made = SegmentationToZones(*seg, *grid, options.outline);
    if (!made.ok()) return ctx.Fail(kCmd, made.status());
    zones = std::move(made).value();
  }
  if (Status w = WriteZonesGeoJson(zones, o.out); !w.ok()) return ctx.Fail(kCmd, w);
  int rooms = 0, corridors = 0;
  for (const Zone& z : zones) (z.kind == "corridor" ? corridors : rooms) += 1;
  report["zones"] = zones.size();
  report["rooms"] = rooms;
  report["corridors"] = corridors;
  report["out"] = o.out;
  report["total_ms"] =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (o.json) {
    std::printf("%s\n", report.dump(2).c_str());
    return;
  }
  std::printf("zones segment: %zu zones (%d rooms, %d corridors) -> %s in %.0f ms\n", zones.size(),
              rooms, corridors, o.out.c_str(), report["total_ms"].get<double>());
  if (report.contains("score")) {
    const auto& s = report["score"];
    std::printf(
        "score: precision %.1f %% recall %.1f %% mean IoU %.1f %% (all cells %.1f %%, over the "
        "%d GT rooms the map shows %.1f %%) (%d GT rooms, %d segments, segmentation %.0f ms)\n",
        100.0 * s["precision"].get<double>(), 100.0 * s["recall"].get<double>(),
        100.0 * s["mean_iou"].get<double>(), 100.0 * s["mean_iou_full"].get<double>(),
        s["gt_rooms_shown"].get<int>(), 100.0 * s["mean_iou_shown"].get<double>(),
        s["gt_rooms"].get<int>(), s["segments"].get<int>(), report["segment_ms"].get<double>());
  }
}

}  // namespace

void AddZonesSegmentCommand(CLI::App& app, CommandContext& ctx) {
  auto opts = std::make_shared<SegmentOpts>();
  CLI::App* cmd = AddZonesSubcommand(
      app, "segment",
      "Automatic zones: room segmentation of an occupancy grid, or keyframe clusters");
  cmd->add_option("map", opts->map,
                  "occupancy grid: ROS map YAML, PNG floor plan (white free, black occupied), or "
                  "RTAB-Map database (Admin.opt_map); omit to zone the --db keyframes alone");
  cmd->add_option("--out", opts->out, "output GeoJSON zone file")->required();
  cmd->add_option("--score", opts->score_gt,
                  "ground-truth PNG (one flat colour per room, black = none): print precision, "
                  "recall, mean IoU");
  cmd->add_option("--db", opts->db, "zonemap map database whose keyframes cap or make the zones");
  cmd->add_option("--max-zone-keyframes", opts->max_zone_keyframes,
                  "split zones holding more keyframes than this (0 = no cap; needs --db)");
  cmd->add_option("--resolution", opts->resolution_m,
                  "metres per pixel of a PNG map (default 0.05) or override of the YAML's");
  cmd->add_option("--cell-size", opts->cell_size_m,
                  "keyframe-only zones: cell size in metres before size-capped splits");
  cmd->add_option("--param", opts->params,
                  "override one segmentation option, KEY=VALUE in metres / m2 (repeatable; "
                  "for evaluation: see docs/segmentation.md)");
  cmd->add_option("--labels", opts->labels_png,
                  "write the segments as a colour PNG over the grid (for inspection)");
  cmd->add_option("--merge-model", opts->merge_model,
                  "layout merge model JSON to use instead of the compiled-in one (training and "
                  "evaluation: scripts/train_layout_merge.py)");
  cmd->add_option("--merge-trace", opts->merge_trace,
                  "write every layout pair's features and ground-truth label (from --score) at "
                  "every merge step to this CSV (training data)");
  cmd->add_flag("--merge-oracle", opts->merge_oracle,
                "with --merge-trace: merge pairs of one ground-truth room instead of asking "
                "the model");
  cmd->add_flag("--json", opts->json, "print a JSON report");
  cmd->callback([opts, &ctx] { Run(*opts, ctx); });
}

}  // namespace zm::app
