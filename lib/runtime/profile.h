// Device profiles: the options every zonemap process reads once at start from a TOML file in
// profiles/ (docs/runtime.md lists every key), plus command-line overrides.
//
// A Profile is made of the options structs the modules own, filled directly: the budget
// (budget.h), the memory policy (memory/policy.h), GetZone's hysteresis (zones/zone_index.h),
// the localizer (localization/localizer.h), the loop (tick_loop.h) and telemetry
// (telemetry.h). There are no mirrored copies here: a default lives in its module's struct,
// and a shipped profile states the values it wants.
//
// Invariants:
//   - A loaded Profile is complete and valid: every field holds the file's value or the module's
//     default, ranges are checked, and the memory split adds up (os reserve + model + headroom +
//     map share <= device memory) or loading fails.
//   - An unknown key, a wrong type or a bad value is an error naming the file and the full key
//     ("profiles/host.toml: unknown key 'map.slot_byte'"); nothing is silently ignored. Sections
//     that belong to the evaluation harness ([cotenant]) are declared, not read, by the core.
//   - Nothing here is consulted inside the tick loop: read the struct, then keep it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "common/param.h"
#include "common/status.h"
#include "localization/localizer.h"
#include "memory/policy.h"
#include "runtime/budget.h"
#include "runtime/input_gate.h"
#include "runtime/pose_output.h"
#include "runtime/profile_reader.h"
#include "runtime/telemetry.h"
#include "runtime/tick_loop.h"
#include "zones/zone_index.h"

namespace zm {

// A profile is the loop's configuration (tick_loop.h's LoopConfig: device, model, map, policy,
// zones, localizer, loop) plus what only the process around the loop reads (telemetry, the
// input gate, the pose lines to the robot).
struct Profile : LoopConfig {
  std::string source;          // the file it was read from
  std::string description;
  TelemetryOptions telemetry;  // [loop] telemetry_flush_ticks
  InputOptions input;          // [input]: the input gate (input_gate.h)
  PoseOutputOptions output;    // [output]: status and covariance of the pose lines (pose_output.h)
};

// Sections of the profile file that belong to the evaluation harness, not to the core: the core
// accepts them without reading them (the harness reads them with the same document).
inline constexpr std::string_view kHarnessProfileSections[] = {"cotenant"};

// Reads the core's sections from `doc` (leaves harness sections for their owner). Validates the
// memory split. Does not call doc.Finish().
[[nodiscard]] Result<Profile> ReadProfile(ProfileDocument& doc);

// Loads a profile for a program that links only the core (zonemapd): the core's sections, the
// harness's sections skipped, every other key an error.
[[nodiscard]] Result<Profile> LoadProfile(const std::string& name_or_path);
// The same from TOML text (tests); `source` names it in errors.
[[nodiscard]] Result<Profile> ParseProfile(std::string_view toml_text, const std::string& source);

// The map share of this profile (budget.h's MapShareBytes over its sections).
[[nodiscard]] Result<std::uint64_t> MapShareBytes(const Profile& profile);

// K_max and the arena for a map of `keyframe_count` keyframes whose largest resident keyframe is
// `largest_keyframe_bytes`, under this profile's policy (budget.h's DeriveBudget).
[[nodiscard]] Result<Budget> DeriveBudget(const Profile& profile,
                                          std::uint64_t largest_keyframe_bytes,
                                          std::uint64_t keyframe_count);

// --memory-thr, declared once for zonemapd, `zonemap run`, `zonemap budget`, `zonemap arena` and the
// public API (MapLoopOptions::memory_thr, ManagerOptions' count and share): one grammar, one parser.
inline constexpr TextParam kMemoryThrParam{
    "memory-thr", "MemoryThr: N keyframes, BYTES (e.g. 512MiB), or N,BYTES (both: the smaller)"};

// --memory-thr: a plain integer is a keyframe count, a number with a unit is bytes, and
// "COUNT,BYTES" sets both (K_max = min(count, bytes / slot_bytes)).
struct MemoryThr {
  std::optional<std::uint64_t> keyframes;
  std::optional<std::uint64_t> bytes;
};
[[nodiscard]] Result<MemoryThr> ParseMemoryThr(std::string_view text);

// Command-line overrides of the core; each set field replaces the profile's value.
struct ProfileOverrides {
  std::optional<std::string> policy;       // --policy
  std::optional<std::string> memory_thr;   // --memory-thr N|BYTES|N,BYTES
  std::optional<double> rate_hz;           // --rate-hz
  std::optional<std::string> process_cap;  // --process-cap BYTES ("0" = none)
  std::optional<std::string> lock_arena;   // --lock-arena on|off (map.lock_arena)
};
// Applies overrides and re-validates. A count from --memory-thr replaces the count and keeps the
// profile's byte share; bytes replace the share and keep the count.
[[nodiscard]] Status ApplyOverrides(const ProfileOverrides& overrides, Profile& profile);

// Checks the memory split of a profile (after loading or overrides). Errors name the keys.
[[nodiscard]] Status ValidateMemorySplit(const Profile& profile);

}  // namespace zm
