// Device profiles: the plain options struct every zonemap process reads once at start from a TOML
// file in profiles/ (docs/runtime-infra.md lists every key), plus command-line overrides.
//
// Invariants:
//   - A loaded Profile is complete and valid: every field holds either the file's value or the
//     documented default, ranges are checked, and the memory split adds up (os reserve +
//     co-tenant + headroom + map share <= device memory) or loading fails.
//   - An unknown key, a wrong type or a bad value is an error naming the file and the full key
//     ("profiles/host.toml: unknown key 'map.slot_byte'"); nothing is silently ignored.
//   - Nothing here is consulted inside the tick loop: read the struct, then keep it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "arena/arena.h"
#include "common/status.h"

namespace zm {

enum class PolicyKind { kSemantic, kBasic, kRadius, kPredictive, kOracle, kUnbounded };

// "semantic", "basic", ... (the names used in profiles, on the command line and in summary.json).
[[nodiscard]] std::string_view PolicyKindName(PolicyKind kind);
[[nodiscard]] Result<PolicyKind> ParsePolicyKind(std::string_view name);

struct DeviceOptions {
  std::string name = "unnamed";
  std::string power_mode;                  // for reports only ("15W", "MAXN SUPER")
  std::uint64_t memory_bytes = 0;          // device (unified) memory; the ledger's total
  std::uint64_t os_reserve_bytes = 0;      // OS + JetPack/CUDA baseline, never available to us
  double memory_bandwidth_gbps = 0.0;      // reference only (datasheet), never used to scale
  double cpu_max_ghz = 0.0;                // reference only
};

struct MapOptions {
  std::uint64_t memory_thr_keyframes = 0;  // MemoryThr as a count; 0 = no count limit
  std::uint64_t map_share_bytes = 0;       // explicit map share; 0 = derived (MapShareBytes())
  std::uint64_t headroom_bytes = 0;        // working headroom left free when deriving the share
  std::uint64_t overhead_bytes = 0;        // map process memory besides keyframe slots
  std::uint64_t slot_bytes = 0;            // 0 = from the database's largest payload
  bool lock_arena = false;                 // mlock the arena
  bool prefault_arena = false;             // MAP_POPULATE the arena
  std::uint64_t process_cap_bytes = 0;     // setrlimit cap for the map process; 0 = none
};

// RTAB-Map's memory management defaults (docs/basic-baseline.md).
struct BasicPolicyOptions {
  std::uint32_t stm_size = 10;                 // Mem/STMSize
  std::uint32_t max_retrieved = 2;             // Mem/MaxRetrieved (per tick)
  std::uint32_t max_local_retrieved = 2;       // RGBD/MaxLocalRetrieved
  double local_radius_m = 10.0;                // RGBD/LocalRadius
  double local_immunization_ratio = 0.25;      // RGBD/LocalImmunizationRatio
  bool transfer_sorting_by_weight_id = false;  // Mem/TransferSortingByWeightId
  bool init_wm_with_all_nodes = false;         // Mem/InitWMWithAllNodes
};

// Autoware-style dynamic map loading by distance tiles.
struct RadiusPolicyOptions {
  double tile_m = 20.0;             // square tile edge
  double map_radius_m = 30.0;       // tiles whose centre lies within this radius are resident
  double update_distance_m = 20.0;  // re-plan after moving this far
};

struct PredictivePolicyOptions {
  std::uint32_t max_keyframes_per_tick = 0;  // prefetch budget per tick; 0 = unlimited
  double max_ms_per_tick = 0.0;              // prefetch time budget per tick; 0 = unlimited
};

struct ProfilePolicyOptions {  // not memory/policy.h's PolicyOptions: this is the profile's view
  PolicyKind kind = PolicyKind::kSemantic;
  double hysteresis_m = 0.5;  // zone boundary hysteresis
  BasicPolicyOptions basic;
  RadiusPolicyOptions radius;
  PredictivePolicyOptions predictive;
};

struct LocalizationOptions {
  double radius_m = 10.0;            // candidate keyframes within this distance of the pose
  double max_heading_deg = 60.0;     // and within this heading difference
  std::uint32_t min_inliers = 20;    // PnP inliers to accept a correction (Vis/MinInliers)
  double ratio = 0.8;                // nearest-neighbour distance ratio (Vis/CorNNDR)
  std::uint32_t max_hamming = 64;    // binary descriptor distance cut-off (bits)
  double ransac_reproj_px = 2.0;     // Vis/PnPReprojError
  std::uint32_t ransac_iterations = 300;
};

struct LoopOptions {
  double rate_hz = 1.0;                   // RTAB-Map's default detection rate (Rtabmap/DetectionRate)
  std::uint32_t telemetry_flush_ticks = 10;  // flush ticks.jsonl every N ticks (and at exit)
  bool realtime = false;                  // pace ticks to rate_hz on the wall clock (live input)
};

struct CotenantOptionsInProfile {
  std::string model = "qwen3-vl-2b";    // a name of CotenantModels() (cotenant.h)
  std::uint64_t weights_bytes = 0;      // 0 = the model table's size
  std::uint64_t overhead_bytes = 0;     // KV cache, activations, runtime besides the weights
  std::uint32_t prompt_tokens = 256;
  std::uint32_t answer_tokens = 64;
  std::uint32_t prompt_batch_tokens = 64;  // prompt tokens processed per pass over the weights
  double request_period_s = 0.0;        // start a request every period; 0 = back to back
  double request_deadline_s = 0.0;      // a request slower than this is a stall; 0 = none
};

struct Profile {
  std::string source;  // the file it was read from
  DeviceOptions device;
  MapOptions map;
  ProfilePolicyOptions policy;
  LocalizationOptions localization;
  LoopOptions loop;
  CotenantOptionsInProfile cotenant;
};

// Loads a profile: a bare name ("orin-nano-8gb") resolves to <profiles dir>/<name>.toml, anything
// containing '/' or ending in ".toml" is a path. See ProfileSearchDirs() for the search order.
[[nodiscard]] Result<Profile> LoadProfile(const std::string& name_or_path);
// Parses a profile from TOML text; `source` names it in errors.
[[nodiscard]] Result<Profile> ParseProfile(std::string_view toml_text, const std::string& source);

// Directories searched for bare profile names, in order: $ZM_PROFILES_DIR, the build's source
// tree (compile-time ZM_PROFILES_DIR), then <executable dir>/../../profiles,
// <executable dir>/../../../profiles and <executable dir>/../share/zonemap/profiles.
[[nodiscard]] std::vector<std::string> ProfileSearchDirs();

// The co-tenant's weights in the profile (the explicit value or the model table's).
[[nodiscard]] Result<std::uint64_t> CotenantWeightsBytes(const Profile& profile);

// The map's share of device memory in bytes: map.map_share_bytes if set, else
// device.memory - os_reserve - (co-tenant weights + overhead) - map.headroom. 0 = no byte limit
// (only when device.memory_bytes is 0).
[[nodiscard]] Result<std::uint64_t> MapShareBytes(const Profile& profile);

// The arena configuration for a database whose largest keyframe payload is
// largest_payload_bytes (used when map.slot_bytes is 0): K_max = min(memory_thr_keyframes,
// (map share - overhead) / slot_bytes). The unbounded policy gets no limits (caller sizes it).
[[nodiscard]] Result<ArenaConfig> MakeArenaConfig(const Profile& profile,
                                                  std::uint64_t largest_payload_bytes);

// "1.9GB", "512MiB", "4096", "2G": bytes. K/M/G and KiB/MiB/GiB are binary (1024^n), KB/MB/GB
// decimal (1000^n), B or nothing is bytes; a decimal fraction is allowed with a unit.
[[nodiscard]] Result<std::uint64_t> ParseBytes(std::string_view text);

// --memory-thr: a plain integer is a keyframe count, a number with a unit is bytes, and
// "COUNT,BYTES" sets both (K_max = min(count, bytes / slot_bytes)).
struct MemoryThr {
  std::optional<std::uint64_t> keyframes;
  std::optional<std::uint64_t> bytes;
};
[[nodiscard]] Result<MemoryThr> ParseMemoryThr(std::string_view text);

// Command-line overrides; each set field replaces the profile's value.
struct ProfileOverrides {
  std::optional<std::string> policy;      // --policy
  std::optional<std::string> memory_thr;  // --memory-thr N|BYTES|N,BYTES
  std::optional<std::string> cotenant;    // --cotenant MODEL
  std::optional<double> rate_hz;          // --rate-hz
  std::optional<std::string> process_cap; // --process-cap BYTES ("0" = none)
};
// Applies overrides and re-validates. A count from --memory-thr replaces the count and keeps the
// profile's byte share; bytes replace the share and keep the count. --cotenant changes the model
// but not the map share (a derived share is computed with the profile's model and frozen).
[[nodiscard]] Status ApplyOverrides(const ProfileOverrides& overrides, Profile& profile);

// Human-readable bytes for reports: "1.90 GB (1.77 GiB)".
[[nodiscard]] std::string FormatBytes(std::uint64_t bytes);

}  // namespace zm
