// `zonemap arena`: reserve the keyframe arena a budget derives and report the plan and its
// statistics, the first thing to check on a device (does the budget fit, is it locked, how many
// slots). The budget is the one DeriveBudget's (runtime/budget.h), from --memory-thr in the
// grammar every other entry point takes (N keyframes, BYTES, or N,BYTES), and the arena takes
// exactly the slot count and aligned slot size it returns.
#include <chrono>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <vector>

#include "arena/arena.h"
#include "commands.h"
#include "param_options.h"
#include "runtime/budget.h"
#include "runtime/profile.h"

namespace zm::app {

void AddArenaCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string memory_thr;
    std::uint64_t keyframes = 0;
    std::uint64_t slot_bytes = 0;
    bool lock = false;
    bool prefault = false;
    bool json = false;
  };
  auto opts = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("arena", "Reserve the keyframe arena for a budget and report it");
  AddParamOption(*cmd, kMemoryThrParam, &opts->memory_thr);
  cmd->add_option("--keyframes", opts->keyframes,
                  "keyframes in the map (default: no map, the budget alone decides)");
  cmd->add_option("--slot-bytes", opts->slot_bytes, "the largest keyframe: bytes per slot")
      ->required();
  cmd->add_flag("--lock", opts->lock, "mlock the reservation");
  cmd->add_flag("--prefault", opts->prefault, "pre-fault every page (MAP_POPULATE)");
  cmd->add_flag("--json", opts->json, "print JSON");
  cmd->callback([opts, &ctx] {
    if (opts->memory_thr.empty() && opts->keyframes == 0) {
      return ctx.Fail("arena", "no budget: give --memory-thr (N, BYTES or N,BYTES) or --keyframes");
    }
    BudgetInputs in;
    in.largest_keyframe_bytes = opts->slot_bytes;
    in.map.slot_bytes = opts->slot_bytes;
    // Without a map the budget alone limits the arena (the largest count a SlotIndex can name).
    in.keyframe_count =
        opts->keyframes != 0 ? opts->keyframes : std::numeric_limits<std::uint32_t>::max() - 1;
    if (!opts->memory_thr.empty()) {
      auto thr = ParseMemoryThr(opts->memory_thr);
      if (!thr.ok()) return ctx.Fail("arena", thr.status());
      in.map.memory_thr_keyframes = thr->keyframes.value_or(0);
      in.map.map_share_bytes = thr->bytes.value_or(0);
    }
    auto budget = DeriveBudget(in);
    if (!budget.ok()) return ctx.Fail("arena", budget.status());
    const auto t0 = std::chrono::steady_clock::now();
    auto created = Arena::Create({.memory_thr_keyframes = budget->arena_slots,
                                  .budget_bytes = 0,
                                  .slot_bytes = budget->arena_slot_bytes,
                                  .lock = opts->lock,
                                  .prefault = opts->prefault});
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (auto* err = std::get_if<ArenaError>(&created)) return ctx.Fail("arena", err->message);
    Arena& arena = std::get<Arena>(created);
    // Fill it once to show acquisition is refused at capacity, not beyond.
    std::vector<SlotIndex> held;
    held.reserve(arena.capacity());
    while (auto s = arena.TryAcquire()) held.push_back(*s);
    const bool refused_when_full = !arena.TryAcquire().has_value();
    const ArenaStats st = arena.stats();
    if (opts->json) {
      nlohmann::json j = {{"capacity", st.capacity},         {"slot_bytes", st.slot_bytes},
                          {"bytes_reserved", st.bytes_reserved}, {"high_water", st.high_water},
                          {"refused", st.refused},           {"refused_when_full", refused_when_full},
                          {"locked", opts->lock},            {"reserve_ms", ms},
                          {"k_max", budget->k_max}};
      std::printf("%s\n", j.dump(2).c_str());
    } else {
      std::printf("arena: %u slots x %llu bytes = %.2f MiB reserved in %.2f ms%s\n", st.capacity,
                  static_cast<unsigned long long>(st.slot_bytes),
                  static_cast<double>(st.bytes_reserved) / (1024.0 * 1024.0), ms,
                  opts->lock ? " (locked)" : "");
      std::printf("arena: filled to %u/%u, next acquisition %s\n", st.high_water, st.capacity,
                  refused_when_full ? "refused (never grows)" : "NOT refused: bug");
    }
  });
}

}  // namespace zm::app
