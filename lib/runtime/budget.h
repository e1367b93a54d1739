// The memory budget: how much of the device the keyframe map may hold, and K_max.
//
// This is the ONE derivation of K_max (docs/style.md §14): the tick loop, `zonemap arena`, the
// evaluation harness and the public API all call DeriveBudget(). Inputs are plain options read
// once from a profile (profile.h) plus two facts of the map database (its largest resident
// keyframe and its keyframe count); nothing here allocates after it returns.
//
//   map share     = map.map_share_bytes if set, else
//                   device.memory - device.os_reserve - model (weights + KV cache) - headroom
//   localization  = the map's vocabulary (Vocabulary::memory_bytes) + the front-end's frame
//                   scratch (FrameScratch::ReservedBytes(FrameScratchBytesFor(image size))),
//                   each when there is one (issue 26)
//   keyframe room = map share - map.overhead (the map process's memory besides its slots and
//                   localization's) - localization
//   slot_bytes    = map.slot_bytes if set, else the database's largest resident keyframe
//   K_max         = min(map.memory_thr_keyframes, keyframes in map, the largest k with
//                   k * slot_bytes + index(k) <= keyframe room), where index(k) is what the
//                   inverted index over k slots reserves (VocabularyIndexBytes; 0 without a
//                   vocabulary): every resident keyframe costs its slot and its postings
//                   (a limit of 0 is "none"; with no limit at all K_max is the whole map)
//   arena slots   = K_max for the bounded policies (the arena makes exceeding K_max physically
//                   impossible); the whole map for basic and unbounded, which model RTAB-Map's
//                   heap: their residency grows and is measured against K_max, not capped.
//   index bytes   = index(arena slots): the index has a place for every arena slot.
// The tick loop reserves exactly these: arena slots x arena_slot_bytes, the index over the arena
// slots, the frame scratch (TickLoop::Create checks both against the budget).
//
// Errors name the quantity and the limit ("map.slot_bytes 4096 is smaller than the largest
// keyframe (2200000 bytes)").
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"
#include "memory/policy_kind.h"

namespace zm {

// The device the map shares. Report-only fields say so.
struct DeviceOptions {
  std::string name = "unnamed";        // reports only
  std::string power_mode;              // reports only ("15W", "MAXN SUPER")
  std::uint64_t memory_bytes = 0;      // device (unified) memory; 0 = unknown (no byte budget)
  std::uint64_t os_reserve_bytes = 0;  // OS + JetPack/CUDA baseline, never available to us
  // The swap the device's OS gives its processes: "none", or "zram" of swap_bytes (JetPack's
  // nvzramconfig: half the memory). Never part of a budget (a swapped keyframe is not resident);
  // the evaluation harness builds it for the device under test (docs/harness.md).
  std::string swap = "none";
  std::uint64_t swap_bytes = 0;
};

// The AI model (VLM/LLM) the map shares the device with: what the map must leave free for it.
struct ModelOptions {
  std::string name;                   // reports only ("qwen3-vl-2b")
  std::uint64_t weights_bytes = 0;    // model weights as loaded
  std::uint64_t kv_cache_bytes = 0;   // KV cache + activations at the context the robot uses
};

// The map process's budget and arena.
struct MapOptions {
  std::uint64_t memory_thr_keyframes = 0;  // MemoryThr as a count (RTAB-Map's); 0 = no count limit
  std::uint64_t map_share_bytes = 0;       // explicit map share; 0 = derived from device and model
  std::uint64_t headroom_bytes = 0;        // left free when deriving the share (page cache, bursts)
  std::uint64_t overhead_bytes = 0;        // map process memory besides keyframe slots
  std::uint64_t slot_bytes = 0;            // 0 = the database's largest resident keyframe
  // mlock a bounded policy's arena (needs RLIMIT_MEMLOCK; the systemd unit sets LimitMEMLOCK).
  // Basic's and unbounded's arena is RTAB-Map's growing heap, which nobody locks: ignored there.
  bool lock_arena = false;
  bool prefault_arena = false;          // MAP_POPULATE: the budget is resident from the start
  std::uint64_t process_cap_bytes = 0;  // setrlimit cap of the map process; 0 = none
};

// What localization holds beside the keyframe slots, known before the loop starts (issue 26).
struct LocalizationInputs {
  std::uint64_t vocabulary_bytes = 0;  // the map's vocabulary (Vocabulary::memory_bytes); 0: none
  std::uint32_t vocabulary_words = 0;  // its words: the index's word lists
  std::uint32_t word_features = 500;   // words per keyframe in the index (LocalizerConfig's)
  // Camera frames (the front-end extracts in the tick): their size; 0 x 0 when frames carry
  // features. scratch_bytes: the front-end's region if set (OrbOptions), else sized from it.
  std::uint32_t image_width = 0;
  std::uint32_t image_height = 0;
  std::uint64_t scratch_bytes = 0;
};

struct BudgetInputs {
  DeviceOptions device;
  ModelOptions model;
  MapOptions map;
  LocalizationInputs localization;
  std::uint64_t largest_keyframe_bytes = 0;  // the database's largest resident keyframe
  std::uint64_t keyframe_count = 0;          // keyframes in the map
  bool bounded_policy = true;                // false for basic and unbounded (see above)
  bool unbounded_policy = false;             // the "unbounded" policy ignores every limit
};

struct Budget {
  std::uint64_t map_share_bytes = 0;      // 0 = no byte limit
  std::uint64_t keyframe_bytes = 0;       // map share - overhead; 0 = no byte limit
  std::uint64_t slot_bytes = 0;
  std::uint32_t k_max = 0;                // MemoryThr in keyframes (>= 1)
  std::uint32_t arena_slots = 0;          // what the arena reserves
  // slot_bytes as the arena aligns it (arena.h's ArenaSlotBytes; page-aligned for the whole-map
  // arenas of basic and unbounded, whose slots go back to the kernel): the arena reserves exactly
  // arena_slots x arena_slot_bytes, nothing recomputed.
  std::uint64_t arena_slot_bytes = 0;
  bool bounded = true;                    // the arena caps residency at k_max
  // Localization's memory beside the slots (0 where there is none): the map's vocabulary, the
  // inverted index over the arena's slots, the front-end's frame scratch.
  std::uint64_t vocabulary_bytes = 0;
  std::uint64_t index_bytes = 0;
  std::uint64_t frame_scratch_bytes = 0;
};

// The map share alone (map.map_share_bytes, or derived); 0 when the device memory is unknown
// and no share is given. Errors when the device has nothing left for the map.
[[nodiscard]] Result<std::uint64_t> MapShareBytes(const DeviceOptions& device,
                                                  const ModelOptions& model, const MapOptions& map);

// The inputs for a map of `keyframe_count` keyframes whose largest resident keyframe is
// `largest_keyframe_bytes`, under `policy` (whose traits decide bounded and unbounded). The one
// place a run's options become BudgetInputs: the tick loop and a profile's DeriveBudget call it.
[[nodiscard]] BudgetInputs BudgetInputsFor(const DeviceOptions& device, const ModelOptions& model,
                                           const MapOptions& map, PolicyKind policy,
                                           std::uint64_t largest_keyframe_bytes,
                                           std::uint64_t keyframe_count);

// K_max, slot size and arena size for one map under one policy. See the header comment.
[[nodiscard]] Result<Budget> DeriveBudget(const BudgetInputs& inputs);

// Human-readable bytes for reports and errors: "1.90 GB (1.77 GiB)".
[[nodiscard]] std::string FormatBytes(std::uint64_t bytes);

}  // namespace zm
