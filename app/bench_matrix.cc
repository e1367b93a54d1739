// `zonemap bench`'s matrix runner (bench_matrix.h).
#include "bench_matrix.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "harness/device_run.h"
#include "harness/experiment_profile.h"
#include "harness/repeats.h"
#include "mapdb/map_db.h"
#include "sim/scenario.h"

namespace zm::app {
namespace {

namespace fs = std::filesystem;

std::string SelfExe() {
  std::error_code ec;
  auto p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("zonemap") : p.string();
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// Generates a scenario with this very program (`zonemap sim ...`) unless it is already there.
Status EnsureScenario(const std::string& spec, const std::string& dir,
                      const std::string& floorplans, bool quick) {
  if (fs::exists(dir + "/scenario.json") && fs::exists(dir + "/map.db")) return Status::Ok();
  if (spec.rfind("dir:", 0) == 0) {  // an existing scenario directory: used as it is
    return NotFound("scenario directory '" + spec.substr(4) +
                    "' has no scenario.json and map.db (make one with `zonemap sim`)");
  }
  std::string cmd = Quote(SelfExe()) + " sim ";
  if (spec == "hospital") {
    cmd += "hospital --seed 1 --quiet --out " + Quote(dir);
    if (quick) cmd += " --area 2000 --tasks 12";
  } else if (spec.rfind("floorplan:", 0) == 0) {
    const std::string name = spec.substr(10);
    const std::string map = floorplans + "/" + name + "_map.png";
    const std::string gt = floorplans + "/" + name + "_gt.png";
    if (!fs::exists(map)) return NotFound("floor plan '" + map + "' does not exist");
    cmd +=
        "floorplan " + Quote(map) + " --gt " + Quote(gt) + " --seed 1 --quiet --out " + Quote(dir);
    if (quick) cmd += " --tasks 8";
  } else {
    return InvalidArgument("unknown scenario '" + spec + "' (hospital or floorplan:NAME)");
  }
  std::fprintf(stderr, "bench: generating %s\n", spec.c_str());
  if (std::system(cmd.c_str()) != 0) return Internal("scenario generation failed: " + cmd);
  return Status::Ok();
}

double Num(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
}

}  // namespace

Result<PolicyVariant> ParsePolicyVariant(const std::string& entry) {
  PolicyVariant v;
  const auto colon = entry.find(':');
  v.policy = entry.substr(0, colon);
  v.label = entry;
  if (colon != std::string::npos) {
    if (entry.substr(colon + 1) != "unsliced") {
      return InvalidArgument("policy variant '" + entry + "': only NAME:unsliced is known");
    }
    v.unsliced = true;
  }
  return v;
}

Result<std::vector<BenchCell>> PlanBenchCells(const BenchMatrixOptions& o) {
  fs::create_directories(o.out);
  std::vector<BenchCell> cells;
  for (const std::string& spec : o.scenarios) {
    std::string name = spec.substr(spec.find(':') == std::string::npos ? 0 : spec.find(':') + 1);
    std::string sdir = o.out + "/scenarios/" + name;
    if (spec.rfind("dir:", 0) == 0) {
      sdir = spec.substr(4);
      name = fs::path(sdir).lexically_normal().filename().string();
      if (name.empty())
        name = fs::path(sdir).lexically_normal().parent_path().filename().string();
    }
    ZM_RETURN_IF_ERROR(EnsureScenario(spec, sdir, o.floorplans, o.quick));
    auto info = sim::LoadScenario(sdir);
    if (!info.ok()) return info.status();
    // Budget sweep from metadata: a fraction of the map, or the two largest zones.
    auto db = MapDb::Open(info->map_db);
    if (!db.ok()) return db.status();
    auto sizes = db.value()->ZoneSizes();
    if (!sizes.ok()) return sizes.status();
    std::vector<std::uint32_t> zs = sizes.value();
    std::sort(zs.rbegin(), zs.rend());
    const std::uint64_t n = db.value()->metadata().keyframe_count;
    db.value().reset();
    for (const std::string& b : o.budgets) {
      std::uint64_t k = 0;
      if (b == "two-zones") {
        k = zs.size() >= 2 ? zs[0] + zs[1] : n;
      } else if (b.size() > 2 && b.substr(b.size() - 2) == "kf") {  // "400kf": a count
        k = std::strtoull(b.c_str(), nullptr, 10);
      } else {
        k = static_cast<std::uint64_t>(
            std::llround(std::atof(b.c_str()) * static_cast<double>(n)));
      }
      k = std::clamp<std::uint64_t>(k, zs.empty() ? 1 : zs[0], n);
      for (const std::string& model : o.models) {
        for (const std::string& entry : o.policies) {
          auto variant = ParsePolicyVariant(entry);
          if (!variant.ok()) return variant.status();
          if (model != "none" && variant->policy == "oracle")
            continue;  // a bound, not a contender
          BenchCell c{name, sdir, b, k, model, variant.value(), {}};
          c.run_name = variant->policy + (variant->unsliced ? "-unsliced" : "") + "-k" +
                       std::to_string(k) + "-" + model;
          cells.push_back(std::move(c));
        }
      }
    }
  }
  return cells;
}

Result<nlohmann::json> RunBenchMatrix(const BenchMatrixOptions& o,
                                      const std::vector<BenchCell>& cells,
                                      const std::atomic<bool>* stop) {
  // The runs, interleaved: repeat r of every cell, then repeat r + 1.
  std::vector<std::vector<nlohmann::json>> summaries(cells.size(),
                                                     std::vector<nlohmann::json>(o.repeats));
  const std::vector<CellRepeat> order = InterleavedOrder(cells.size(), o.repeats);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const BenchCell& c = cells[order[i].cell];
    const std::uint32_t rep = order[i].repeat;
    ZM_ASSIGN_OR_RETURN(ExperimentProfile profile, LoadExperimentProfile(o.profile));
    ProfileOverrides ov;
    ov.policy = c.variant.policy;
    ov.memory_thr = std::to_string(c.k);
    if (!o.lock_arena.empty()) ov.lock_arena = o.lock_arena;
    ZM_RETURN_IF_ERROR(ApplyOverrides(ov, profile.core));
    if (c.variant.unsliced) profile.core.loads.sliced = false;
    if (c.model != "none") ZM_RETURN_IF_ERROR(ApplyModelOverride(c.model, profile));
    // The profile's request length (512 + 128 for the paper's device) unless asked otherwise.
    if (o.prompt_tokens != 0) profile.cotenant.prompt_tokens = o.prompt_tokens;
    if (o.answer_tokens != 0) profile.cotenant.answer_tokens = o.answer_tokens;
    DeviceRunRequest req = o.run;
    req.scenario_dir = c.scenario_dir;
    req.out_dir =
        o.out + "/runs/" + c.scenario_name + "/" + c.run_name + "/rep" + std::to_string(rep);
    req.profile = std::move(profile);
    req.with_cotenant = c.model != "none";
    std::fprintf(stderr, "bench: %s %s repeat %u/%u (run %zu of %zu)\n", c.scenario_name.c_str(),
                 c.run_name.c_str(), rep + 1, o.repeats, i + 1, order.size());
    auto r = RunOnDevice(req, stop);
    if (!r.ok()) return r.status().Annotate(c.run_name);
    summaries[order[i].cell][rep] = ToJson(r.value());
    if (stop != nullptr && stop->load()) return FailedPrecondition("interrupted");
  }

  // Per cell: every repeat's summary, the statistics over them, the representative repeat.
  nlohmann::json all = nlohmann::json::array();
  for (std::size_t ci = 0; ci < cells.size(); ++ci) {
    const BenchCell& c = cells[ci];
    const std::vector<nlohmann::json>& runs = summaries[ci];
    std::vector<double> tick_means;
    nlohmann::json dirs = nlohmann::json::array();
    for (std::uint32_t r = 0; r < o.repeats; ++r) {
      tick_means.push_back(Num(runs[r]["tick_ms"], "mean"));
      dirs.push_back("runs/" + c.scenario_name + "/" + c.run_name + "/rep" + std::to_string(r));
    }
    const std::size_t rep = RepresentativeRepeat(tick_means);
    const nlohmann::json& first = runs[0];
    all.push_back({{"scenario_name", c.scenario_name},
                   {"cell", c.run_name},
                   {"policy", c.variant.policy},
                   {"policy_label", c.variant.label},
                   {"budget", c.budget},
                   {"model", c.model},
                   {"k_max", first.value("k_max", std::uint64_t{0})},
                   {"repeats", o.repeats},
                   {"order", "interleaved"},
                   // The run the figures show: mean tick time nearest the median of the repeats.
                   {"representative_repeat", rep},
                   {"representative_by", "/tick_ms/mean"},
                   {"run_dirs", dirs},
                   {"stats", StatsOfSummaries(runs)},
                   {"runs", runs}});
  }
  std::ofstream(o.out + "/results.json") << all.dump(2) << '\n';
  return all;
}

}  // namespace zm::app
