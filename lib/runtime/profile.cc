// Profile loading: a strict reader over toml++ that marks every key it consumes, so whatever is
// left over is an unknown key and an error; toml++'s exceptions stop here and become a Status.
#include "runtime/profile.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <toml++/toml.h>

#include "runtime/cotenant.h"

#ifndef ZM_PROFILES_DIR
#define ZM_PROFILES_DIR ""
#endif

namespace zm {
namespace {

constexpr std::array<std::pair<PolicyKind, std::string_view>, 6> kPolicyNames = {{
    {PolicyKind::kSemantic, "semantic"},
    {PolicyKind::kBasic, "basic"},
    {PolicyKind::kRadius, "radius"},
    {PolicyKind::kPredictive, "predictive"},
    {PolicyKind::kOracle, "oracle"},
    {PolicyKind::kUnbounded, "unbounded"},
}};

std::string TypeName(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table: return "table";
    case toml::node_type::array: return "array";
    case toml::node_type::string: return "string";
    case toml::node_type::integer: return "integer";
    case toml::node_type::floating_point: return "float";
    case toml::node_type::boolean: return "boolean";
    case toml::node_type::date: return "date";
    case toml::node_type::time: return "time";
    case toml::node_type::date_time: return "date-time";
    default: return "nothing";
  }
}

// Reads one TOML table. Every accessor marks its key as known; Finish() reports the first key
// nobody asked for. The first error wins and later calls are no-ops, so a caller can read a
// whole section and check once.
class TableReader {
 public:
  TableReader(const toml::table* table, std::string prefix, const std::string* file,
              Status* error)
      : table_(table), prefix_(std::move(prefix)), file_(file), error_(error) {}

  void String(std::string_view key, std::string& out) {
    const toml::node* n = Find(key);
    if (n == nullptr) return;
    if (!n->is_string()) return Fail(*n, key, "must be a string, got " + TypeName(*n));
    out = n->as_string()->get();
  }

  void Bool(std::string_view key, bool& out) {
    const toml::node* n = Find(key);
    if (n == nullptr) return;
    if (!n->is_boolean()) return Fail(*n, key, "must be true or false, got " + TypeName(*n));
    out = n->as_boolean()->get();
  }

  void U64(std::string_view key, std::uint64_t& out, std::uint64_t min = 0,
           std::uint64_t max = std::numeric_limits<std::uint64_t>::max()) {
    const toml::node* n = Find(key);
    if (n == nullptr) return;
    if (!n->is_integer()) return Fail(*n, key, "must be an integer, got " + TypeName(*n));
    const std::int64_t v = n->as_integer()->get();
    if (v < 0 || static_cast<std::uint64_t>(v) < min || static_cast<std::uint64_t>(v) > max) {
      return Fail(*n, key, "is " + std::to_string(v) + ", must be in [" + std::to_string(min) +
                               ", " + std::to_string(max) + "]");
    }
    out = static_cast<std::uint64_t>(v);
  }

  void U32(std::string_view key, std::uint32_t& out, std::uint32_t min = 0,
           std::uint32_t max = std::numeric_limits<std::uint32_t>::max()) {
    std::uint64_t v = out;
    U64(key, v, min, max);
    out = static_cast<std::uint32_t>(v);
  }

  // An integer number of bytes or a string with a unit ("1.75GiB", "1.9GB").
  void Bytes(std::string_view key, std::uint64_t& out) {
    const toml::node* n = Find(key);
    if (n == nullptr) return;
    if (n->is_integer()) {
      const std::int64_t v = n->as_integer()->get();
      if (v < 0) return Fail(*n, key, "is negative (" + std::to_string(v) + ")");
      out = static_cast<std::uint64_t>(v);
      return;
    }
    if (n->is_string()) {
      Result<std::uint64_t> b = ParseBytes(n->as_string()->get());
      if (!b.ok()) return Fail(*n, key, b.status().message());
      out = *b;
      return;
    }
    Fail(*n, key, "must be bytes (an integer or a string such as \"1.5GiB\"), got " + TypeName(*n));
  }

  void Double(std::string_view key, double& out, double min, double max) {
    const toml::node* n = Find(key);
    if (n == nullptr) return;
    double v = 0.0;
    if (n->is_floating_point()) {
      v = n->as_floating_point()->get();
    } else if (n->is_integer()) {
      v = static_cast<double>(n->as_integer()->get());
    } else {
      return Fail(*n, key, "must be a number, got " + TypeName(*n));
    }
    if (!std::isfinite(v) || v < min || v > max) {
      std::ostringstream s;
      s << "is " << v << ", must be in [" << min << ", " << max << "]";
      return Fail(*n, key, s.str());
    }
    out = v;
  }

  // A sub-table; absent means all defaults. A non-table value is an error.
  TableReader Sub(std::string_view key) {
    const toml::node* n = Find(key);
    if (n != nullptr && !n->is_table()) {
      Fail(*n, key, "must be a table, got " + TypeName(*n));
      n = nullptr;
    }
    return {n == nullptr ? nullptr : n->as_table(), FullKey(key), file_, error_};
  }

  // Every key of this table must have been read.
  void Finish() {
    if (table_ == nullptr || !error_->ok()) return;
    for (auto&& [k, v] : *table_) {
      if (seen_.count(std::string(k.str())) == 0) {
        *error_ = InvalidArgument(Where(v) + "unknown key '" + FullKey(k.str()) + "'");
        return;
      }
    }
  }

  void FailKey(std::string_view key, const std::string& message) {
    const toml::node* n = table_ == nullptr ? nullptr : table_->get(key);
    if (n != nullptr) {
      Fail(*n, key, message);
    } else if (error_->ok()) {
      *error_ = InvalidArgument(*file_ + ": key '" + FullKey(key) + "' " + message);
    }
  }

 private:
  const toml::node* Find(std::string_view key) {
    seen_.insert(std::string(key));
    if (table_ == nullptr || !error_->ok()) return nullptr;
    return table_->get(key);
  }
  std::string FullKey(std::string_view key) const {
    return prefix_.empty() ? std::string(key) : prefix_ + "." + std::string(key);
  }
  std::string Where(const toml::node& n) const {
    const auto& src = n.source();
    return *file_ + ":" + std::to_string(src.begin.line) + ": ";
  }
  void Fail(const toml::node& n, std::string_view key, const std::string& message) {
    if (!error_->ok()) return;
    *error_ = InvalidArgument(Where(n) + "key '" + FullKey(key) + "' " + message);
  }

  const toml::table* table_;
  std::string prefix_;
  const std::string* file_;
  Status* error_;
  std::set<std::string> seen_;
};

Status ValidateMemorySplit(const Profile& p) {
  const std::string& f = p.source;
  if (p.device.memory_bytes != 0 && p.device.os_reserve_bytes >= p.device.memory_bytes) {
    return InvalidArgument(f + ": device.os_reserve_bytes (" + FormatBytes(p.device.os_reserve_bytes) +
                           ") must be below device.memory_bytes (" +
                           FormatBytes(p.device.memory_bytes) + ")");
  }
  ZM_ASSIGN_OR_RETURN(const std::uint64_t share, MapShareBytes(p));
  if (share != 0 && p.map.overhead_bytes >= share) {
    return InvalidArgument(f + ": map.overhead_bytes (" + FormatBytes(p.map.overhead_bytes) +
                           ") leaves nothing of the map share (" + FormatBytes(share) +
                           ") for keyframes");
  }
  if (p.map.process_cap_bytes != 0 && share != 0 && p.map.process_cap_bytes < share) {
    return InvalidArgument(f + ": map.process_cap_bytes (" + FormatBytes(p.map.process_cap_bytes) +
                           ") is below the map share (" + FormatBytes(share) + ")");
  }
  return Status::Ok();
}

Status Validate(const Profile& p) {
  const std::string& f = p.source;
  if (p.cotenant.weights_bytes == 0 && !FindCotenantModel(p.cotenant.model).ok()) {
    return InvalidArgument(f + ": key 'cotenant.model' names an unknown model '" + p.cotenant.model +
                           "' and cotenant.weights_bytes is not set (known: " +
                           CotenantModelNames() + ")");
  }
  return ValidateMemorySplit(p);
}

std::string ExecutableDir() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

}  // namespace

std::string_view PolicyKindName(PolicyKind kind) {
  for (const auto& [k, n] : kPolicyNames) {
    if (k == kind) return n;
  }
  return "unknown";
}

Result<PolicyKind> ParsePolicyKind(std::string_view name) {
  for (const auto& [k, n] : kPolicyNames) {
    if (n == name) return k;
  }
  return InvalidArgument("unknown policy '" + std::string(name) +
                         "' (semantic, basic, radius, predictive, oracle, unbounded)");
}

Result<std::uint64_t> ParseBytes(std::string_view text) {
  const std::string original(text);
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  std::size_t digits = 0;
  while (digits < text.size() &&
         ((text[digits] >= '0' && text[digits] <= '9') || text[digits] == '.')) {
    ++digits;
  }
  std::string_view number = text.substr(0, digits);
  std::string_view unit = text.substr(digits);
  while (!unit.empty() && unit.front() == ' ') unit.remove_prefix(1);
  if (number.empty()) return InvalidArgument("'" + original + "' is not a byte size");
  struct Unit {
    std::string_view name;
    double factor;
  };
  static constexpr std::array<Unit, 14> kUnits = {{
      {"", 1.0}, {"B", 1.0},
      {"K", 1024.0}, {"KiB", 1024.0}, {"M", 1048576.0}, {"MiB", 1048576.0},
      {"G", 1073741824.0}, {"GiB", 1073741824.0}, {"T", 1099511627776.0},
      {"TiB", 1099511627776.0},
      {"KB", 1e3}, {"MB", 1e6}, {"GB", 1e9}, {"TB", 1e12},
  }};
  const Unit* found = nullptr;
  for (const Unit& u : kUnits) {
    if (u.name == unit) found = &u;
  }
  if (found == nullptr) {
    return InvalidArgument("'" + original + "' has an unknown unit '" + std::string(unit) +
                           "' (B, K, M, G, T, KiB, MiB, GiB, TiB, KB, MB, GB, TB)");
  }
  if (number.find('.') != std::string_view::npos) {
    if (found->factor == 1.0) {
      return InvalidArgument("'" + original + "': a fractional byte count needs a unit");
    }
    const std::string n(number);
    char* end = nullptr;
    const double v = std::strtod(n.c_str(), &end);
    if (end != n.c_str() + n.size() || !std::isfinite(v)) {
      return InvalidArgument("'" + original + "' is not a byte size");
    }
    const double bytes = std::round(v * found->factor);
    if (bytes >= 1.8e19) return OutOfRange("'" + original + "' exceeds 2^64 bytes");
    return static_cast<std::uint64_t>(bytes);
  }
  std::uint64_t v = 0;
  const auto [ptr, ec] = std::from_chars(number.data(), number.data() + number.size(), v);
  if (ec != std::errc() || ptr != number.data() + number.size()) {
    return InvalidArgument("'" + original + "' is not a byte size");
  }
  const auto factor = static_cast<std::uint64_t>(found->factor);
  if (v != 0 && factor > std::numeric_limits<std::uint64_t>::max() / v) {
    return OutOfRange("'" + original + "' exceeds 2^64 bytes");
  }
  return v * factor;
}

Result<MemoryThr> ParseMemoryThr(std::string_view text) {
  MemoryThr thr;
  const std::string original(text);
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    std::string_view part = text.substr(0, comma);
    text = comma == std::string_view::npos ? std::string_view() : text.substr(comma + 1);
    while (!part.empty() && part.front() == ' ') part.remove_prefix(1);
    while (!part.empty() && part.back() == ' ') part.remove_suffix(1);
    const bool plain = !part.empty() && std::all_of(part.begin(), part.end(), [](char c) {
      return c >= '0' && c <= '9';
    });
    if (plain) {
      std::uint64_t v = 0;
      const auto [ptr, ec] = std::from_chars(part.data(), part.data() + part.size(), v);
      if (ec != std::errc() || v == 0 || thr.keyframes) {
        return InvalidArgument("--memory-thr '" + original +
                               "': the keyframe count must be a positive integer, given once");
      }
      thr.keyframes = v;
    } else {
      Result<std::uint64_t> b = ParseBytes(part);
      if (!b.ok() || *b == 0 || thr.bytes) {
        return InvalidArgument("--memory-thr '" + original +
                               "': expected N (keyframes), BYTES with a unit (512MiB, 1.9GB) or "
                               "N,BYTES");
      }
      thr.bytes = *b;
    }
  }
  if (!thr.keyframes && !thr.bytes) return InvalidArgument("--memory-thr is empty");
  return thr;
}

std::string FormatBytes(std::uint64_t bytes) {
  char buf[64];
  const double b = static_cast<double>(bytes);
  if (bytes >= 1000000000ULL) {
    std::snprintf(buf, sizeof buf, "%.2f GB (%.2f GiB)", b / 1e9, b / 1073741824.0);
  } else if (bytes >= 1000000ULL) {
    std::snprintf(buf, sizeof buf, "%.2f MB (%.2f MiB)", b / 1e6, b / 1048576.0);
  } else {
    std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  }
  return buf;
}

std::vector<std::string> ProfileSearchDirs() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("ZM_PROFILES_DIR"); env != nullptr && *env != '\0') {
    dirs.emplace_back(env);
  }
  if (std::string_view(ZM_PROFILES_DIR).size() > 0) dirs.emplace_back(ZM_PROFILES_DIR);
  if (const std::string exe = ExecutableDir(); !exe.empty()) {
    dirs.push_back(exe + "/../../profiles");
    dirs.push_back(exe + "/../../../profiles");
    dirs.push_back(exe + "/../share/zonemap/profiles");
  }
  return dirs;
}

Result<Profile> ParseProfile(std::string_view toml_text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    return InvalidArgument(source + ":" + std::to_string(where.line) + ": " +
                           std::string(e.description()));
  }
  Profile p;
  p.source = source;
  Status error;
  TableReader top(&root, "", &source, &error);
  std::string description;
  top.String("description", description);

  TableReader device = top.Sub("device");
  device.String("name", p.device.name);
  device.String("power_mode", p.device.power_mode);
  device.Bytes("memory_bytes", p.device.memory_bytes);
  device.Bytes("os_reserve_bytes", p.device.os_reserve_bytes);
  device.Double("memory_bandwidth_gbps", p.device.memory_bandwidth_gbps, 0.0, 1e5);
  device.Double("cpu_max_ghz", p.device.cpu_max_ghz, 0.0, 100.0);
  device.Finish();

  TableReader map = top.Sub("map");
  map.U64("memory_thr_keyframes", p.map.memory_thr_keyframes);
  map.Bytes("map_share_bytes", p.map.map_share_bytes);
  map.Bytes("headroom_bytes", p.map.headroom_bytes);
  map.Bytes("overhead_bytes", p.map.overhead_bytes);
  map.Bytes("slot_bytes", p.map.slot_bytes);
  map.Bool("lock_arena", p.map.lock_arena);
  map.Bool("prefault_arena", p.map.prefault_arena);
  map.Bytes("process_cap_bytes", p.map.process_cap_bytes);
  map.Finish();

  TableReader policy = top.Sub("policy");
  std::string policy_name(PolicyKindName(p.policy.kind));
  policy.String("name", policy_name);
  if (error.ok()) {
    Result<PolicyKind> kind = ParsePolicyKind(policy_name);
    if (kind.ok()) {
      p.policy.kind = *kind;
    } else {
      policy.FailKey("name", kind.status().message());
    }
  }
  policy.Double("hysteresis_m", p.policy.hysteresis_m, 0.0, 100.0);
  TableReader basic = policy.Sub("basic");
  basic.U32("stm_size", p.policy.basic.stm_size);
  basic.U32("max_retrieved", p.policy.basic.max_retrieved);
  basic.U32("max_local_retrieved", p.policy.basic.max_local_retrieved);
  basic.Double("local_radius_m", p.policy.basic.local_radius_m, 0.0, 1e6);
  basic.Double("local_immunization_ratio", p.policy.basic.local_immunization_ratio, 0.0, 1.0);
  basic.Bool("transfer_sorting_by_weight_id", p.policy.basic.transfer_sorting_by_weight_id);
  basic.Bool("init_wm_with_all_nodes", p.policy.basic.init_wm_with_all_nodes);
  basic.Finish();
  TableReader radius = policy.Sub("radius");
  radius.Double("tile_m", p.policy.radius.tile_m, 0.1, 1e6);
  radius.Double("map_radius_m", p.policy.radius.map_radius_m, 0.0, 1e6);
  radius.Double("update_distance_m", p.policy.radius.update_distance_m, 0.0, 1e6);
  radius.Finish();
  TableReader predictive = policy.Sub("predictive");
  predictive.U32("max_keyframes_per_tick", p.policy.predictive.max_keyframes_per_tick);
  predictive.Double("max_ms_per_tick", p.policy.predictive.max_ms_per_tick, 0.0, 1e6);
  predictive.Finish();
  policy.Finish();

  TableReader loc = top.Sub("localization");
  loc.Double("radius_m", p.localization.radius_m, 0.0, 1e6);
  loc.Double("max_heading_deg", p.localization.max_heading_deg, 0.0, 180.0);
  loc.U32("min_inliers", p.localization.min_inliers, 3);
  loc.Double("ratio", p.localization.ratio, 0.0, 1.0);
  loc.U32("max_hamming", p.localization.max_hamming, 0, 256);
  loc.Double("ransac_reproj_px", p.localization.ransac_reproj_px, 0.01, 1e3);
  loc.U32("ransac_iterations", p.localization.ransac_iterations, 1, 1000000);
  loc.Finish();

  TableReader loop = top.Sub("loop");
  loop.Double("rate_hz", p.loop.rate_hz, 0.001, 10000.0);
  loop.U32("telemetry_flush_ticks", p.loop.telemetry_flush_ticks, 1);
  loop.Bool("realtime", p.loop.realtime);
  loop.Finish();

  TableReader co = top.Sub("cotenant");
  co.String("model", p.cotenant.model);
  co.Bytes("weights_bytes", p.cotenant.weights_bytes);
  co.Bytes("overhead_bytes", p.cotenant.overhead_bytes);
  co.U32("prompt_tokens", p.cotenant.prompt_tokens);
  co.U32("answer_tokens", p.cotenant.answer_tokens, 1);
  co.U32("prompt_batch_tokens", p.cotenant.prompt_batch_tokens, 1);
  co.Double("request_period_s", p.cotenant.request_period_s, 0.0, 1e6);
  co.Double("request_deadline_s", p.cotenant.request_deadline_s, 0.0, 1e6);
  co.Finish();

  top.Finish();
  if (!error.ok()) return error;
  ZM_RETURN_IF_ERROR(Validate(p));
  return p;
}

Result<Profile> LoadProfile(const std::string& name_or_path) {
  std::string path;
  const bool is_path = name_or_path.find('/') != std::string::npos ||
                       (name_or_path.size() > 5 &&
                        name_or_path.compare(name_or_path.size() - 5, 5, ".toml") == 0);
  if (is_path) {
    path = name_or_path;
  } else {
    if (name_or_path.empty()) return InvalidArgument("empty profile name");
    const std::vector<std::string> dirs = ProfileSearchDirs();
    for (const std::string& d : dirs) {
      std::error_code ec;
      const std::string candidate = d + "/" + name_or_path + ".toml";
      if (std::filesystem::is_regular_file(candidate, ec)) {
        path = std::filesystem::weakly_canonical(candidate, ec).string();
        if (ec) path = candidate;
        break;
      }
    }
    if (path.empty()) {
      std::string searched;
      for (const std::string& d : dirs) searched += (searched.empty() ? "" : ", ") + d;
      return NotFound("profile '" + name_or_path + "' not found (searched " + searched +
                      "; set ZM_PROFILES_DIR)");
    }
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("profile file '" + path + "' cannot be opened");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return IoError("profile file '" + path + "': read failed");
  return ParseProfile(text.str(), path);
}

Result<std::uint64_t> CotenantWeightsBytes(const Profile& profile) {
  if (profile.cotenant.weights_bytes != 0) return profile.cotenant.weights_bytes;
  ZM_ASSIGN_OR_RETURN(const CotenantModel model, FindCotenantModel(profile.cotenant.model));
  return model.weights_bytes;
}

Result<std::uint64_t> MapShareBytes(const Profile& profile) {
  if (profile.map.map_share_bytes != 0) return profile.map.map_share_bytes;
  if (profile.device.memory_bytes == 0) return std::uint64_t{0};
  ZM_ASSIGN_OR_RETURN(const std::uint64_t weights, CotenantWeightsBytes(profile));
  const std::uint64_t taken = profile.device.os_reserve_bytes + weights +
                              profile.cotenant.overhead_bytes + profile.map.headroom_bytes;
  if (taken >= profile.device.memory_bytes) {
    return InvalidArgument(profile.source + ": no map share left: os reserve " +
                           FormatBytes(profile.device.os_reserve_bytes) + " + co-tenant " +
                           FormatBytes(weights + profile.cotenant.overhead_bytes) + " + headroom " +
                           FormatBytes(profile.map.headroom_bytes) + " >= device memory " +
                           FormatBytes(profile.device.memory_bytes) +
                           " (set map.map_share_bytes explicitly or shrink one)");
  }
  return profile.device.memory_bytes - taken;
}

Result<ArenaConfig> MakeArenaConfig(const Profile& profile, std::uint64_t largest_payload_bytes) {
  ArenaConfig config;
  config.slot_bytes = profile.map.slot_bytes != 0 ? profile.map.slot_bytes : largest_payload_bytes;
  config.lock = profile.map.lock_arena;
  config.prefault = profile.map.prefault_arena;
  if (config.slot_bytes == 0) {
    return InvalidArgument(profile.source +
                           ": slot size unknown (map.slot_bytes = 0 and no payload size given)");
  }
  if (largest_payload_bytes > config.slot_bytes) {
    return OutOfRange(profile.source + ": map.slot_bytes " + std::to_string(config.slot_bytes) +
                      " is smaller than the database's largest keyframe payload " +
                      std::to_string(largest_payload_bytes));
  }
  if (profile.policy.kind == PolicyKind::kUnbounded) return config;
  config.memory_thr_keyframes = profile.map.memory_thr_keyframes;
  ZM_ASSIGN_OR_RETURN(const std::uint64_t share, MapShareBytes(profile));
  if (share != 0) {
    if (profile.map.overhead_bytes >= share) {
      return OutOfRange(profile.source + ": map overhead " + FormatBytes(profile.map.overhead_bytes) +
                        " leaves nothing of the map share " + FormatBytes(share));
    }
    config.budget_bytes = share - profile.map.overhead_bytes;
  }
  return config;
}

Status ApplyOverrides(const ProfileOverrides& o, Profile& profile) {
  if (o.policy) {
    ZM_ASSIGN_OR_RETURN(profile.policy.kind, ParsePolicyKind(*o.policy));
  }
  if (o.memory_thr) {
    ZM_ASSIGN_OR_RETURN(const MemoryThr thr, ParseMemoryThr(*o.memory_thr));
    if (thr.keyframes) profile.map.memory_thr_keyframes = *thr.keyframes;
    if (thr.bytes) profile.map.map_share_bytes = *thr.bytes;
  }
  if (o.cotenant) {
    ZM_ASSIGN_OR_RETURN(const CotenantModel model, FindCotenantModel(*o.cotenant));
    // The map share was planned for the profile's co-tenant: another model runs beside the same
    // share (as in the paper, MemoryThr is fixed while models change), so freeze it first.
    if (profile.map.map_share_bytes == 0) {
      ZM_ASSIGN_OR_RETURN(profile.map.map_share_bytes, MapShareBytes(profile));
    }
    profile.cotenant.model = std::string(model.name);
    profile.cotenant.weights_bytes = 0;  // the table's size for the new model
  }
  if (o.rate_hz) {
    if (!(*o.rate_hz > 0.0) || !std::isfinite(*o.rate_hz)) {
      return InvalidArgument("--rate-hz must be a positive number");
    }
    profile.loop.rate_hz = *o.rate_hz;
  }
  if (o.process_cap) {
    if (*o.process_cap == "0") {
      profile.map.process_cap_bytes = 0;
    } else {
      ZM_ASSIGN_OR_RETURN(profile.map.process_cap_bytes, ParseBytes(*o.process_cap));
    }
  }
  return ValidateMemorySplit(profile).Annotate("after command-line overrides");
}

}  // namespace zm
