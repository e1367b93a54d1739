// Profile loading: the core's sections, read straight into the modules' options structs.
#include "runtime/profile.h"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace zm {

Status ValidateMemorySplit(const Profile& p) {
  const std::string& f = p.source;
  if (p.device.memory_bytes != 0 && p.device.os_reserve_bytes >= p.device.memory_bytes) {
    return InvalidArgument(f + ": device.os_reserve_bytes (" + FormatBytes(p.device.os_reserve_bytes) +
                           ") must be below device.memory_bytes (" +
                           FormatBytes(p.device.memory_bytes) + ")");
  }
  Result<std::uint64_t> share = MapShareBytes(p);
  if (!share.ok()) return share.status().Annotate(f);
  if (*share != 0 && p.map.overhead_bytes >= *share) {
    return InvalidArgument(f + ": map.overhead_bytes (" + FormatBytes(p.map.overhead_bytes) +
                           ") leaves nothing of the map share (" + FormatBytes(*share) +
                           ") for keyframes");
  }
  if (p.map.process_cap_bytes != 0 && *share != 0 && p.map.process_cap_bytes < *share) {
    return InvalidArgument(f + ": map.process_cap_bytes (" + FormatBytes(p.map.process_cap_bytes) +
                           ") is below the map share (" + FormatBytes(*share) + ")");
  }
  return Status::Ok();
}

Result<Profile> ReadProfile(ProfileDocument& doc) {
  Profile p;
  p.source = doc.source();
  TableReader& top = doc.root();
  top.String("description", p.description);

  TableReader device = top.Sub("device");
  device.String("name", p.device.name);
  device.String("power_mode", p.device.power_mode);
  device.Bytes("memory_bytes", p.device.memory_bytes);
  device.Bytes("os_reserve_bytes", p.device.os_reserve_bytes);
  device.String("swap", p.device.swap);
  device.Bytes("swap_bytes", p.device.swap_bytes);
  if (p.device.swap != "none" && p.device.swap != "zram") {
    device.FailKey("swap", "must be \"none\" or \"zram\", not \"" + p.device.swap + "\"");
  } else if (p.device.swap == "zram" && p.device.swap_bytes == 0) {
    device.FailKey("swap_bytes", "must be > 0 with swap = \"zram\"");
  } else if (p.device.swap == "none" && p.device.swap_bytes != 0) {
    device.FailKey("swap_bytes",
                   "must be 0 with swap = \"none\", not " + FormatBytes(p.device.swap_bytes));
  }
  device.Finish();

  TableReader model = top.Sub("model");
  model.String("name", p.model.name);
  model.Bytes("weights_bytes", p.model.weights_bytes);
  model.Bytes("kv_cache_bytes", p.model.kv_cache_bytes);
  model.Finish();

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
  std::string policy_name(PolicyName(p.policy.kind));
  policy.String("name", policy_name);
  if (policy.ok()) {
    Result<PolicyKind> kind = ParsePolicyKind(policy_name);  // parsed once, here
    if (kind.ok()) {
      p.policy.kind = *kind;
    } else {
      policy.FailKey("name", kind.status().message());
    }
  }
  policy.Double("hysteresis_m", p.zones.hysteresis_m, 0.0, 100.0);
  TableReader basic = policy.Sub("basic");
  BasicOptions& b = p.policy.basic;
  basic.U32("max_retrieved", b.max_retrieved);
  basic.U32("max_local_retrieved", b.max_local_retrieved);
  basic.Double("local_radius_m", b.local_radius_m, 0.0, 1e6);
  basic.Double("local_immunization_ratio", b.local_immunization_ratio, 0.0, 1.0);
  basic.Bool("transfer_sorting_by_weight_id", b.transfer_sorting_by_weight_id);
  basic.Bool("init_wm_with_all_nodes", b.init_wm_with_all_nodes);
  basic.Finish();
  TableReader radius = policy.Sub("radius");
  radius.Double("tile_m", p.policy.radius.tile_m, 0.1, 1e6);
  radius.Double("map_radius_m", p.policy.radius.map_radius_m, 0.0, 1e6);
  radius.Double("update_distance_m", p.policy.radius.update_distance_m, 0.0, 1e6);
  radius.Finish();
  TableReader predictive = policy.Sub("predictive");
  predictive.Bool("prefetch", p.policy.predictive.prefetch);
  predictive.Finish();
  policy.Finish();

  TableReader loads = top.Sub("loads");
  LoadSliceOptions& lo = p.loads;
  loads.Bool("sliced", lo.sliced);
  loads.Double("tick_ms", lo.tick_ms, 0.0, 1e6);
  loads.Bytes("tick_bytes", lo.tick_bytes);
  loads.Double("idle_ms", lo.idle_ms, 0.0, 1e6);
  loads.Bytes("idle_bytes", lo.idle_bytes);
  loads.Double("margin_ms", lo.margin_ms, 0.0, 1e6);
  loads.Finish();

  TableReader loc = top.Sub("localization");
  LocalizerConfig& l = p.localizer;
  loc.Double("radius_m", l.radius_m, 0.0, 1e6);
  double heading_deg = l.max_heading_diff_rad * 180.0 / M_PI;
  loc.Double("max_heading_deg", heading_deg, 0.0, 180.0);
  l.max_heading_diff_rad = heading_deg * M_PI / 180.0;
  loc.U32("min_inliers", l.min_inliers, 6);
  double ratio = l.ratio;
  loc.Double("ratio", ratio, 0.0, 1.0);
  l.ratio = static_cast<float>(ratio);
  loc.U32("max_hamming", l.max_hamming, 0, 256);
  loc.Double("ransac_reproj_px", l.ransac_reprojection_px, 0.01, 1e3);
  std::uint32_t iterations = static_cast<std::uint32_t>(l.ransac_iterations);
  loc.U32("ransac_iterations", iterations, 1, 1000000);
  l.ransac_iterations = static_cast<int>(iterations);
  // The closure gate (localization/closure_gate.h): closure_gate_m 0 turns it off.
  loc.Double("closure_gate_m", l.gate.base_m, 0.0, 1e3);
  loc.Double("closure_gate_per_m", l.gate.per_m, 0.0, 10.0);
  loc.Double("closure_gate_deg", l.gate.rotation_deg, 0.001, 180.0);
  loc.Double("closure_gate_deg_per_m", l.gate.rotation_per_m_deg, 0.0, 180.0);
  loc.U32("relocalize_after", l.gate.agree, 1, 1000);
  loc.Finish();

  TableReader loop = top.Sub("loop");
  loop.Double("rate_hz", p.loop.rate_hz, 0.001, 10000.0);
  loop.U32("telemetry_flush_ticks", p.telemetry.flush_ticks, 1);
  loop.Finish();

  TableReader input = top.Sub("input");
  input.Double("max_distance_from_map_m", p.input.max_distance_from_map_m, 0.0, 1e6);
  input.Double("quaternion_tolerance", p.input.quaternion_tolerance, 0.0, 0.5);
  input.U32("max_route_waypoints", p.input.max_route_waypoints, 0, 1u << 20);
  input.Finish();

  TableReader output = top.Sub("output");
  PoseOutputOptions& o = p.output;
  output.Double("map_sigma_m", o.map_sigma_m, 0.0, 1e3);
  output.Double("map_sigma_deg", o.map_sigma_deg, 0.0, 180.0);
  output.Double("initial_sigma_m", o.initial_sigma_m, 0.0, 1e6);
  output.Double("initial_sigma_deg", o.initial_sigma_deg, 0.0, 180.0);
  output.Double("odom_sigma_m_per_sqrt_m", o.odom_sigma_m_per_sqrt_m, 0.0, 100.0);
  output.Double("odom_sigma_deg_per_sqrt_m", o.odom_sigma_deg_per_sqrt_m, 0.0, 180.0);
  output.Double("lost_sigma_m", o.lost_sigma_m, 0.0, 1e6);
  output.Finish();

  if (!doc.error().ok()) return doc.error();
  ZM_RETURN_IF_ERROR(ValidateMemorySplit(p));
  return p;
}

namespace {
Result<Profile> ReadCoreOnly(ProfileDocument& doc) {
  ZM_ASSIGN_OR_RETURN(Profile p, ReadProfile(doc));
  for (std::string_view section : kHarnessProfileSections) doc.SkipSection(section);
  ZM_RETURN_IF_ERROR(doc.Finish());
  return p;
}
}  // namespace

Result<Profile> LoadProfile(const std::string& name_or_path) {
  ZM_ASSIGN_OR_RETURN(ProfileDocument doc, ProfileDocument::Load(name_or_path));
  return ReadCoreOnly(doc);
}

Result<Profile> ParseProfile(std::string_view toml_text, const std::string& source) {
  ZM_ASSIGN_OR_RETURN(ProfileDocument doc, ProfileDocument::Parse(toml_text, source));
  return ReadCoreOnly(doc);
}

Result<std::uint64_t> MapShareBytes(const Profile& profile) {
  return MapShareBytes(profile.device, profile.model, profile.map);
}

Result<Budget> DeriveBudget(const Profile& profile, std::uint64_t largest_keyframe_bytes,
                            std::uint64_t keyframe_count) {
  Result<Budget> b =
      DeriveBudget(BudgetInputsFor(profile.device, profile.model, profile.map,
                                   profile.policy.kind, largest_keyframe_bytes, keyframe_count));
  if (!b.ok()) return b.status().Annotate(profile.source);
  return b;
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

Status ApplyOverrides(const ProfileOverrides& o, Profile& profile) {
  if (o.policy) {
    ZM_ASSIGN_OR_RETURN(profile.policy.kind, ParsePolicyKind(*o.policy));
  }
  if (o.memory_thr) {
    ZM_ASSIGN_OR_RETURN(const MemoryThr thr, ParseMemoryThr(*o.memory_thr));
    if (thr.keyframes) profile.map.memory_thr_keyframes = *thr.keyframes;
    if (thr.bytes) profile.map.map_share_bytes = *thr.bytes;
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
  if (o.lock_arena) {
    if (*o.lock_arena != "on" && *o.lock_arena != "off") {
      return InvalidArgument("--lock-arena '" + *o.lock_arena + "': expected on or off");
    }
    profile.map.lock_arena = *o.lock_arena == "on";
  }
  return ValidateMemorySplit(profile).Annotate("after command-line overrides");
}

}  // namespace zm
