// `zonemap budget`: the memory budget (K_max, slot, arena, map share) a run would derive for a
// map of N keyframes whose largest is B bytes, under the same profile and flags as `zonemap run`
// (--profile, --policy, --memory-thr, --cotenant, --device-scale). It calls the one DeriveBudget
// (lib/runtime/budget.h), so scripts ask the program instead of re-deriving K_max
// (scripts/sweep.py, docs/style.md §14).
//
// --stdin serves many maps from one process: "N B" pairs, one a line, each answered by one JSON
// line (an "error" member when DeriveBudget refuses that map); a script walking a grid starts one
// process per profile variant instead of one per point.
#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "harness/device_scale.h"
#include "harness/experiment_profile.h"

namespace zm::app {
namespace {

struct MapFacts {
  std::uint64_t keyframes = 0;
  std::uint64_t largest_keyframe_bytes = 0;
};

nlohmann::json BudgetJson(const MapFacts& map, const Result<Budget>& budget) {
  nlohmann::json j = {{"keyframes", map.keyframes},
                      {"largest_keyframe_bytes", map.largest_keyframe_bytes}};
  if (!budget.ok()) {
    j["error"] = budget.status().message();
    return j;
  }
  const Budget& b = *budget;
  j["map_share_bytes"] = b.map_share_bytes;
  j["keyframe_bytes"] = b.keyframe_bytes;
  j["slot_bytes"] = b.slot_bytes;
  j["k_max"] = b.k_max;
  j["arena_slots"] = b.arena_slots;
  j["bounded"] = b.bounded;
  return j;
}

// "N B" (keyframes, largest keyframe bytes); false for anything else.
bool ParseMapLine(const std::string& line, MapFacts& out) {
  const char* p = line.data();
  const char* end = p + line.size();
  auto number = [&](std::uint64_t& v) {
    while (p < end && (*p == ' ' || *p == '\t')) ++p;
    const auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc()) return false;
    p = next;
    return true;
  };
  if (!number(out.keyframes) || !number(out.largest_keyframe_bytes)) return false;
  while (p < end && (*p == ' ' || *p == '\t' || *p == '\r')) ++p;
  return p == end;
}

}  // namespace

void AddBudgetCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string profile = "host", policy, memory_thr, cotenant, model;
    double device_scale = 1.0;
    MapFacts map;
    bool json = false;
    bool stdin_pairs = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand(
      "budget", "Print the memory budget (K_max, slot, arena, map share) a run would derive");
  cmd->add_option("--profile", o->profile, "device profile name or TOML path (default host)");
  cmd->add_option("--policy", o->policy, "basic|radius|semantic|predictive|oracle|unbounded");
  cmd->add_option("--memory-thr", o->memory_thr, "MemoryThr: N keyframes, BYTES (e.g. 512MiB), or N,BYTES");
  auto* cotenant = cmd->add_option(
      "--cotenant", o->cotenant, "the co-tenant model, as `zonemap run`: the map share stays frozen");
  cmd->add_option("--model", o->model,
                  "a profile written for this model: the map share is derived anew for it")
      ->excludes(cotenant);
  cmd->add_option("--device-scale", o->device_scale, "the device at this fraction of its size (0 < S <= 1)");
  auto* keyframes = cmd->add_option("--keyframes", o->map.keyframes, "keyframes in the map");
  auto* largest = cmd->add_option("--largest-keyframe-bytes", o->map.largest_keyframe_bytes,
                                  "the map's largest resident keyframe (the slot, unless map.slot_bytes is set)");
  auto* pairs = cmd->add_flag("--stdin", o->stdin_pairs,
                              "read 'KEYFRAMES LARGEST_KEYFRAME_BYTES' lines from stdin; one JSON line each");
  pairs->excludes(keyframes)->excludes(largest);
  cmd->add_flag("--json", o->json, "print JSON");
  cmd->callback([o, &ctx, keyframes, largest] {
    if (!o->stdin_pairs && (keyframes->count() == 0 || largest->count() == 0)) {
      return ctx.Fail("budget", "--keyframes and --largest-keyframe-bytes are required (or --stdin)");
    }
    auto profile = LoadExperimentProfile(o->profile);
    if (!profile.ok()) return ctx.Fail("budget", profile.status());
    ProfileOverrides ov;
    if (!o->policy.empty()) ov.policy = o->policy;
    if (!o->memory_thr.empty()) ov.memory_thr = o->memory_thr;
    if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("budget", s);
    if (!o->cotenant.empty() || !o->model.empty()) {
      const bool frozen = !o->cotenant.empty();
      Status s = ApplyModelOverride(frozen ? o->cotenant : o->model, profile.value(),
                                    frozen ? ModelShare::kFrozen : ModelShare::kRederived);
      if (!s.ok()) return ctx.Fail("budget", s);
    }
    // As a run does (harness/device_run.cc): the model override first, then the scale.
    Profile& core = profile->core;
    if (Status s = ValidateDeviceScale(o->device_scale); !s.ok()) return ctx.Fail("budget", s);
    if (Status s = ApplyDeviceScale(o->device_scale, core.device, core.model, core.map); !s.ok()) {
      return ctx.Fail("budget", s);
    }

    if (o->stdin_pairs) {
      std::string line;
      for (std::uint64_t n = 1; std::getline(std::cin, line); ++n) {
        MapFacts map;
        if (!ParseMapLine(line, map)) {
          return ctx.Fail("budget", "stdin line " + std::to_string(n) + " '" + line +
                                        "': expected 'KEYFRAMES LARGEST_KEYFRAME_BYTES'");
        }
        const auto b = DeriveBudget(core, map.largest_keyframe_bytes, map.keyframes);
        std::printf("%s\n", BudgetJson(map, b).dump().c_str());
        std::fflush(stdout);  // the script waits for each answer
      }
      return;
    }
    const auto b = DeriveBudget(core, o->map.largest_keyframe_bytes, o->map.keyframes);
    if (!b.ok()) return ctx.Fail("budget", b.status());
    if (o->json) {
      nlohmann::json j = BudgetJson(o->map, b);
      j["profile"] = core.source;
      j["policy"] = std::string(PolicyName(core.policy.kind));
      j["model"] = core.model.name;
      j["device_scale"] = o->device_scale;
      std::printf("%s\n", j.dump(2).c_str());
      return;
    }
    std::printf("budget: K_max %u keyframes (%s), arena %u slots x %s (%s)\n", b->k_max,
                PolicyName(core.policy.kind).data(), b->arena_slots,
                FormatBytes(b->slot_bytes).c_str(),
                b->bounded ? "bounded: residency never exceeds K_max" : "the whole map");
    std::printf("budget: map share %s, %s of it for keyframes (%s)\n",
                b->map_share_bytes != 0 ? FormatBytes(b->map_share_bytes).c_str() : "unlimited",
                b->keyframe_bytes != 0 ? FormatBytes(b->keyframe_bytes).c_str() : "all",
                core.source.c_str());
  });
}

}  // namespace zm::app
