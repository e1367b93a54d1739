// `zonemap arena`: reserve an arena from a budget and report the plan and its statistics, the
// first thing to check on a device (does the budget fit, is it locked, how many slots).
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <vector>

#include "arena/arena.h"
#include "commands.h"

namespace zm::app {

void AddArenaCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::uint64_t memory_thr = 0;
    std::uint64_t budget_bytes = 0;
    std::uint64_t slot_bytes = 0;
    bool lock = false;
    bool prefault = false;
    bool json = false;
  };
  auto opts = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("arena", "Reserve the keyframe arena for a budget and report it");
  cmd->add_option("--memory-thr", opts->memory_thr, "MemoryThr as a keyframe count (0 = none)");
  cmd->add_option("--budget-bytes", opts->budget_bytes, "map share in bytes (0 = none)");
  cmd->add_option("--slot-bytes", opts->slot_bytes, "bytes per keyframe slot")->required();
  cmd->add_flag("--lock", opts->lock, "mlock the reservation");
  cmd->add_flag("--prefault", opts->prefault, "pre-fault every page (MAP_POPULATE)");
  cmd->add_flag("--json", opts->json, "print JSON");
  cmd->callback([opts, &ctx] {
    const auto t0 = std::chrono::steady_clock::now();
    auto created = Arena::Create({.memory_thr_keyframes = opts->memory_thr,
                                  .budget_bytes = opts->budget_bytes,
                                  .slot_bytes = opts->slot_bytes,
                                  .lock = opts->lock,
                                  .prefault = opts->prefault});
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (auto* err = std::get_if<ArenaError>(&created)) {
      ctx.Fail("arena", err->message);
      return;
    }
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
                          {"locked", opts->lock},            {"reserve_ms", ms}};
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
