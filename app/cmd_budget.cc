// `zonemap budget`: the memory budget (K_max, slot, arena, map share) a run would derive for a
// map of N keyframes whose largest is B bytes, under the same profile and flags as `zonemap run`
// (--profile, --policy, --memory-thr, --cotenant, --device-scale). It calls the one DeriveBudget
// (lib/runtime/budget.h), so scripts ask the program instead of re-deriving K_max
// (scripts/sweep.py, docs/style.md §14).
//
// --list-models prints the co-tenant's model table (harness/cotenant.h's CotenantModels: weights,
// KV bytes per token, sliding window, fixed state) as JSON: the one table, which scripts/sweep.py
// reads instead of keeping a copy.
//
// --stdin serves many maps from one process: "N B" pairs, one a line, each answered by one JSON
// line (an "error" member when DeriveBudget refuses that map); a script walking a grid starts one
// process per profile variant instead of one per point.
//
// --map MAP.db takes the map's own facts instead (its keyframes, its largest, its vocabulary),
// with the frames a run would read (--frames FRAMES.bin) or a camera's size (--images WxH): then
// localization's memory is counted too, the map's vocabulary, the inverted index over the arena's
// slots and the front-end's frame scratch, exactly as the tick loop reserves them
// (TickLoop's LoopBudgetInputs).
#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "harness/cotenant.h"
#include "harness/device_scale.h"
#include "harness/experiment_profile.h"
#include "localization/map_vocabulary.h"
#include "param_options.h"

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
  j["arena_slot_bytes"] = b.arena_slot_bytes;
  j["bounded"] = b.bounded;
  j["vocabulary_bytes"] = b.vocabulary_bytes;
  j["index_bytes"] = b.index_bytes;
  j["frame_scratch_bytes"] = b.frame_scratch_bytes;
  return j;
}

// "WxH", both sides > 0; false for anything else.
bool ParseImageSize(const std::string& text, FrameSource::Images& out) {
  const char* p = text.data();
  const char* end = p + text.size();
  auto side = [&](std::uint32_t& v) {
    const auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc() || v == 0) return false;
    p = next;
    return true;
  };
  if (!side(out.width) || p == end || *p++ != 'x' || !side(out.height) || p != end) return false;
  out.max_colour_bytes = 1;  // camera frames
  return true;
}

// The budget of the map at `map_path` under `config`, with the frames of `frames_path` (or
// images of `image_size`, or none): the loop's inputs (LoopBudgetInputs); the map's facts in
// *facts.
Result<Budget> MapBudget(const LoopConfig& config, const std::string& map_path,
                         const std::string& frames_path, const std::string& image_size,
                         MapFacts* facts) {
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> db, MapDb::Open(map_path));
  ZM_ASSIGN_OR_RETURN(std::optional<Vocabulary> vocabulary, LoadMapVocabulary(*db, map_path));
  FrameSource::Images images;
  if (!frames_path.empty()) {
    ZM_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> frames, OpenReplaySource(frames_path));
    images = frames->images();
  } else if (!image_size.empty() && !ParseImageSize(image_size, images)) {
    return InvalidArgument("--images '" + image_size + "': expected WxH, e.g. 640x480");
  }
  const MapMetadata& meta = db->metadata();
  *facts = {meta.keyframe_count, meta.largest_payload_bytes};
  return DeriveBudget(LoopBudgetInputs(config, meta, vocabulary ? &*vocabulary : nullptr, images));
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
    std::string profile = "host", policy, memory_thr, cotenant, model, map, frames, images;
    double device_scale = 1.0;
    MapFacts map_facts;
    bool json = false;
    bool stdin_pairs = false;
    bool list_models = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand(
      "budget", "Print the memory budget (K_max, slot, arena, map share) a run would derive");
  cmd->add_option("--profile", o->profile, "device profile name or TOML path (default host)");
  cmd->add_option("--policy", o->policy, "basic|radius|semantic|predictive|oracle|unbounded");
  AddParamOption(*cmd, kMemoryThrParam, &o->memory_thr);
  auto* cotenant = cmd->add_option(
      "--cotenant", o->cotenant, "the co-tenant model, as `zonemap run`: the map share stays frozen");
  cmd->add_option("--model", o->model,
                  "a profile written for this model: the map share is derived anew for it")
      ->excludes(cotenant);
  cmd->add_option("--device-scale", o->device_scale, "the device at this fraction of its size (0 < S <= 1)");
  auto* keyframes = cmd->add_option("--keyframes", o->map_facts.keyframes, "keyframes in the map");
  auto* largest = cmd->add_option(
      "--largest-keyframe-bytes", o->map_facts.largest_keyframe_bytes,
      "the map's largest resident keyframe (the slot, unless map.slot_bytes is set)");
  auto* pairs = cmd->add_flag("--stdin", o->stdin_pairs,
                              "read 'KEYFRAMES LARGEST_KEYFRAME_BYTES' lines from stdin; one JSON line each");
  pairs->excludes(keyframes)->excludes(largest);
  auto* map_opt = cmd->add_option(
      "--map", o->map, "the map's own facts: its keyframes, its largest, its vocabulary");
  map_opt->excludes(keyframes)->excludes(largest)->excludes(pairs);
  auto* frames_opt = cmd->add_option("--frames", o->frames,
                                     "with --map: the frames a run reads (their images' size)");
  auto* images_opt =
      cmd->add_option("--images", o->images,
                      "with --map: camera frames of this size, WxH (the front-end's scratch)");
  frames_opt->needs(map_opt)->excludes(images_opt);
  images_opt->needs(map_opt);
  cmd->add_flag("--json", o->json, "print JSON");
  cmd->add_flag("--list-models", o->list_models,
                "print the co-tenant's model table as JSON (weights, KV cache per token) and exit");
  cmd->callback([o, &ctx, keyframes, largest] {
    if (o->list_models) {
      nlohmann::json models = nlohmann::json::array();
      for (const CotenantModel& m : CotenantModels()) {
        models.push_back({{"name", m.name},
                          {"display", m.display},
                          {"weights_bytes", m.weights_bytes},
                          {"kv_bytes_per_token", m.kv_bytes_per_token},
                          {"window_bytes_per_token", m.window_bytes_per_token},
                          {"window_tokens", m.window_tokens},
                          {"state_bytes", m.state_bytes}});
      }
      std::printf("%s\n", models.dump(2).c_str());
      return;
    }
    if (!o->stdin_pairs && o->map.empty() && (keyframes->count() == 0 || largest->count() == 0)) {
      return ctx.Fail(
          "budget", "--keyframes and --largest-keyframe-bytes are required (or --stdin, or --map)");
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
    MapFacts facts = o->map_facts;
    const Result<Budget> b = o->map.empty()
                                 ? DeriveBudget(core, facts.largest_keyframe_bytes, facts.keyframes)
                                 : MapBudget(core, o->map, o->frames, o->images, &facts);
    if (!b.ok()) return ctx.Fail("budget", b.status());
    if (o->json) {
      nlohmann::json j = BudgetJson(facts, b);
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
    std::printf("budget: map share %s, %s of it for keyframes%s (%s)\n",
                b->map_share_bytes != 0 ? FormatBytes(b->map_share_bytes).c_str() : "unlimited",
                b->keyframe_bytes != 0 ? FormatBytes(b->keyframe_bytes).c_str() : "all",
                b->index_bytes != 0 ? " and their postings in the index" : "", core.source.c_str());
    if (b->vocabulary_bytes != 0 || b->frame_scratch_bytes != 0) {
      std::printf(
          "budget: localization %s: vocabulary %s, inverted index %s (%u slots), frame "
          "scratch %s\n",
          FormatBytes(b->vocabulary_bytes + b->index_bytes + b->frame_scratch_bytes).c_str(),
          FormatBytes(b->vocabulary_bytes).c_str(), FormatBytes(b->index_bytes).c_str(),
          b->arena_slots, FormatBytes(b->frame_scratch_bytes).c_str());
    }
  });
}

}  // namespace zm::app
