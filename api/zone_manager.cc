// ZoneManager: the public host-store path as a thin facade over lib/memory (MapIndex,
// MakePolicy, Plan, ExternalWorkingSet) and the runtime's start-up rules (profiles, DeriveBudget,
// map_setup.h), its input gate (input_gate.h) and its decide step (decide_step.h: the zone of
// the pose and the policy's plan, as zonemapd's tick loop decides). Its own logic is only the
// glue: converting poses, and turning the ExternalWorkingSet's lists into answers. Ids, links
// and Status are the core's own types (one definition: lib/common/).
#include "zonemap/zone_manager.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "convert.h"
#include "memory/external_working_set.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "runtime/budget.h"
#include "runtime/decide_step.h"
#include "runtime/input_gate.h"
#include "runtime/map_setup.h"
#include "runtime/profile.h"
#include "zones/annotate.h"
#include "zones/zone_index.h"
#include "zones/zone_set.h"

namespace zonemap {

// The public header states the default in plain C++ (it may include nothing of the core's); the
// doorway band is declared once in zones/annotate.h, and this keeps the two the same.
// Clang 14 cannot evaluate libstdc++ 12's std::string constructor in a constant expression;
// GCC, which builds every target for aarch64, checks it.
#if !defined(__clang__)
static_assert(HostMap{}.doorway_band_m == zm::kDoorwayBandParam.default_value,
              "HostMap::doorway_band_m must default to zones/annotate.h's");
#endif


using internal::ToPose3;

struct ZoneManager::Impl {
  zm::Profile profile;
  zm::ZoneSet zones;
  std::vector<zm::ZoneMember> members;
  zm::MapIndex index;
  zm::Budget budget;
  bool bounded = true;
  std::optional<zm::ZoneIndex> zone_index;  // polygon zones only
  std::optional<zm::InputGate> gate;
  std::unique_ptr<zm::DecideStep> decide;   // the policy, its plan, the zone and the context
  std::unique_ptr<zm::ExternalWorkingSet> residency;
  std::vector<zm::ZoneId> route;
  // Answer buffers, reserved to the map size at Create.
  std::vector<KeyframeId> unload_ids;
  std::vector<KeyframeId> load_ids;
  std::vector<LoadBatch> batches;
  ManagerStats stats;

  Result<Answer> Carry(const zm::Plan& plan, bool startup);
};

namespace {

zm::Status BadOptions(const std::string& m) { return zm::InvalidArgument(m); }

// The profile with the caller's overrides, through the same ApplyOverrides zonemapd uses.
zm::Result<zm::Profile> ProfileFor(const ManagerOptions& o) {
  ZM_ASSIGN_OR_RETURN(zm::Profile p, internal::ProfileOrDefaults(o.profile));
  zm::ProfileOverrides ov;
  if (!o.policy.empty()) ov.policy = o.policy;
  // --memory-thr's syntax: a plain integer is a count, a number with a unit is bytes.
  std::string thr;
  if (o.memory_thr_keyframes != 0) thr = std::to_string(o.memory_thr_keyframes);
  if (o.map_share_bytes != 0) {
    // Appended piece by piece: GCC 12's -O3 -Wrestrict misreads `("" or ",") + std::string` on
    // aarch64 as an overlapping memcpy.
    if (!thr.empty()) thr += ',';
    thr += std::to_string(o.map_share_bytes);
    thr += 'B';
  }
  if (!thr.empty()) ov.memory_thr = thr;
  ZM_RETURN_IF_ERROR(zm::ApplyOverrides(ov, p));
  return p;
}

}  // namespace

Result<std::unique_ptr<ZoneManager>> ZoneManager::Create(const HostMap& map,
                                                         const ManagerOptions& options) {
  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  {
    auto p = ProfileFor(options);
    if (!p.ok()) return p.status();
    m.profile = std::move(p).value();
  }
  if (map.keyframes.empty()) return BadOptions("the host map has no keyframes");
  if (!(options.nearest_keyframe_zone_m > 0.0)) {
    return BadOptions("nearest_keyframe_zone_m must be > 0");
  }

  // Keyframes and links, as the core's metadata records.
  std::vector<zm::KeyframeMeta> keyframes;
  keyframes.reserve(map.keyframes.size());
  std::uint64_t largest = 0;
  for (const KeyframeInfo& k : map.keyframes) {
    const std::string what = "keyframe " + std::to_string(k.id.value);
    if (k.id.value == 0) return BadOptions("keyframe id 0 is reserved for \"none\"");
    auto pose = ToPose3(k.pose, what + " pose");
    if (!pose.ok()) return pose.status();
    if (k.bytes > std::numeric_limits<std::uint32_t>::max()) {
      return zm::OutOfRange(what + " has " + std::to_string(k.bytes) +
                            " bytes; at most 4294967295 are supported");
    }
    zm::KeyframeMeta meta;
    meta.id = k.id;
    meta.pose = pose->pose;
    meta.weight = k.weight;
    meta.payload_bytes = static_cast<std::uint32_t>(k.bytes);
    keyframes.push_back(meta);
    largest = std::max(largest, k.bytes);
  }
  std::vector<zm::LinkRecord> links;
  links.reserve(map.links.size());
  for (const KeyframeLink& l : map.links) {
    zm::LinkRecord r;
    r.from = l.from;
    r.to = l.to;
    r.type = l.kind;
    links.push_back(r);
  }

  // Zones: a zone file (annotated here) or the host's names and memberships.
  const bool host_zones = !map.zone_names.empty() || !map.memberships.empty();
  if (!map.zone_file.empty() && host_zones) {
    return BadOptions(
        "give zones one way: zone_file, or zone_names with memberships (both were given)");
  }
  if (!map.zone_file.empty()) {
    auto zones = zm::LoadZoneFile(map.zone_file);
    if (!zones.ok()) return zones.status();
    zm::AnnotateOptions ao;
    ao.band_m = map.doorway_band_m;
    auto report = zm::AnnotateKeyframes(*zones, keyframes, ao);
    if (!report.ok()) return report.status().Annotate(map.zone_file);
    m.zones = std::move(report->zones);
    m.members = std::move(report->members);
  } else if (host_zones) {
    std::vector<std::vector<zm::KeyframeId>> lists(map.zone_names.size());
    for (const ZoneMembership& z : map.memberships) {
      if (z.zone.value < 0 || static_cast<std::size_t>(z.zone.value) >= map.zone_names.size()) {
        return BadOptions("membership names zone " + std::to_string(z.zone.value) +
                          "; zones are 0.." +
                          std::to_string(static_cast<long>(map.zone_names.size()) - 1) +
                          " (zone_names)");
      }
      lists[static_cast<std::size_t>(z.zone.value)].push_back(z.keyframe);
      m.members.push_back({z.zone, z.keyframe});
    }
    for (std::size_t i = 0; i < map.zone_names.size(); ++i) {
      zm::Zone zone;
      zone.name = map.zone_names[i];
      if (zm::Status s = m.zones.Add(std::move(zone), lists[i], "zone_names[" + std::to_string(i) + "]");
          !s.ok()) {
        return s;
      }
    }
  } else {
    return zm::FailedPrecondition(
        "the host map has no zones: give zone_file, or zone_names with memberships");
  }
  if (m.zones.empty()) return zm::FailedPrecondition("the zone set is empty");

  {
    auto index = zm::BuildPolicyIndex(keyframes, links, m.zones, m.members);
    if (!index.ok()) return index.status();
    m.index = std::move(index).value();
  }

  // K_max: the one derivation. Without keyframe sizes a byte budget cannot be applied.
  auto share = zm::MapShareBytes(m.profile);
  if (!share.ok()) return share.status();
  const zm::PolicyTraits& traits = zm::Traits(m.profile.policy.kind);
  if (largest == 0 && m.profile.map.slot_bytes == 0) {
    if (*share != 0 && traits.has_budget) {
      return BadOptions(
          "the budget is in bytes (map share " + zm::FormatBytes(*share) + " from " +
          m.profile.source + ") but no keyframe gives its size: set KeyframeInfo::bytes, or "
          "map.slot_bytes in the profile, or budget by count (memory_thr_keyframes)");
    }
    largest = 1;  // count-only budget: the slot size is never used
  }
  {
    auto budget = zm::DeriveBudget(m.profile, largest, keyframes.size());
    if (!budget.ok()) return budget.status();
    m.budget = *budget;
  }
  m.bounded = traits.bounded;

  std::vector<zm::ZoneId> future;
  future.reserve(options.oracle_future.size());
  for (ZoneId z : options.oracle_future) {
    if (z != kNoZone && (z.value < 0 || z.value >= m.index.zone_count())) {
      return BadOptions("oracle_future names zone " + std::to_string(z.value) + "; zones are 0.." +
                        std::to_string(m.index.zone_count() - 1));
    }
    future.push_back(z);
  }
  if (!m.zones.has_keyframe_lists()) m.zone_index.emplace(m.zones, m.profile.zones);
  m.route.reserve(4 * static_cast<std::size_t>(m.index.zone_count()));
  {
    zm::PolicyOptions popt = zm::PolicyOptionsFor(m.profile, m.budget, keyframes, std::move(future));
    auto policy = zm::MakePolicy(m.index, popt);
    if (!policy.ok()) return policy.status();
    m.decide = std::make_unique<zm::DecideStep>(
        m.index, std::move(policy).value(),
        zm::DecideOptions{.small_displacement_m = m.profile.loop.small_displacement_m,
                          .small_displacement_rad = m.profile.loop.small_displacement_rad,
                          .nearest_keyframe_zone_m = options.nearest_keyframe_zone_m},
        m.zone_index ? &*m.zone_index : nullptr, m.route);
  }
  // The pose is in the map frame already: the gate's correction is the identity.
  m.gate.emplace(m.profile.input, zm::ExtentOf(m.index));

  m.residency = std::make_unique<zm::ExternalWorkingSet>(m.index);
  m.unload_ids.reserve(m.index.keyframe_count());
  m.load_ids.reserve(m.index.keyframe_count());
  m.batches.reserve((static_cast<std::size_t>(m.index.zone_count()) + 2) * 2);
  return std::unique_ptr<ZoneManager>(new ZoneManager(std::move(impl)));
}

ZoneManager::ZoneManager(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ZoneManager::~ZoneManager() = default;

Result<Answer> ZoneManager::Impl::Carry(const zm::Plan& plan, bool startup) {
  if (zm::Status s = residency->Apply(plan); !s.ok()) return s;
  unload_ids.clear();
  load_ids.clear();
  batches.clear();
  for (zm::KfIndex k : residency->unloads()) unload_ids.push_back(index.id(k));
  for (zm::KfIndex k : residency->loads()) load_ids.push_back(index.id(k));
  for (const auto& b : residency->load_batches()) {
    batches.push_back(LoadBatch{b.zone, b.begin, b.end});
  }
  Answer a;
  a.unload = unload_ids;
  a.load = load_ids;
  a.batches = batches;
  a.zone = decide->zone();
  a.startup = startup;
  a.resident_before = residency->resident_before();
  a.resident_after = residency->resident_count();
  a.peak = residency->peak_during_apply();
  stats.keyframes_loaded += load_ids.size();
  stats.keyframes_unloaded += unload_ids.size();
  stats.zone_loads = decide->policy().zone_loads();
  stats.peak_resident = std::max(stats.peak_resident, a.peak);
  if (a.peak > budget.k_max) {
    ++stats.over_budget_steps;
    if (bounded) {
      return Status(StatusCode::kInternal,
                    "the " + std::string(decide->policy().name()) + " policy's answer holds " +
                        std::to_string(a.peak) + " keyframes at once, above K_max " +
                        std::to_string(budget.k_max) + " (a bug: please report it)");
    }
  }
  return a;
}

Result<Answer> ZoneManager::Update(const TickInput& input) {
  Impl& m = *impl_;
  // Syntax first (finite numbers, a zone that exists), then the input gate's rules (zonemapd's):
  // a refusal changes nothing, the stamp included.
  auto pose = ToPose3(input.pose, "TickInput pose");
  if (!pose.ok()) return pose.status();
  if (input.zone != kNoZone && (input.zone.value < 0 || input.zone.value >= m.index.zone_count())) {
    return Status(StatusCode::kInvalidArgument,
                  "TickInput zone " + std::to_string(input.zone.value) + "; zones are 0.." +
                      std::to_string(m.index.zone_count() - 1) + " (or kNoZone)");
  }
  zm::RejectReason why = zm::RejectReason::kSyntax;
  if (!m.gate->AcceptFrame(input.stamp_s, pose->pose, pose->quaternion_norm,
                           zm::Pose3::Identity(), &why)) {
    return Status(StatusCode::kInvalidArgument,
                  "TickInput refused (" + std::string(zm::RejectReasonName(why)) + "): " +
                      zm::RejectRule(why) + " (stamp_s " + std::to_string(input.stamp_s) +
                      ", quaternion norm " + std::to_string(pose->quaternion_norm) + ")");
  }
  const bool startup = !m.decide->started();
  const zm::Plan& plan = m.decide->Before(input.stamp_s, pose->pose, input.zone);
  ++m.stats.updates;
  return m.Carry(plan, startup);
}

Result<Answer> ZoneManager::AfterLocalization(const LocalizationInput& input) {
  Impl& m = *impl_;
  if (!m.decide->started()) {
    return Status(StatusCode::kFailedPrecondition, "AfterLocalization before the first Update");
  }
  for (KeyframeId id : {input.highest_hypothesis, input.localized_on}) {
    if (id.value != 0 && m.index.Find(id) == zm::kNoKf) {
      return Status(StatusCode::kInvalidArgument,
                    "LocalizationInput names keyframe " + std::to_string(id.value) +
                        ", which is not in the host map");
    }
  }
  return m.Carry(m.decide->After(input.highest_hypothesis, input.localized_on), false);
}

Status ZoneManager::SetRoute(std::span<const ZoneId> route) {
  Impl& m = *impl_;
  for (ZoneId z : route) {
    if (z.value < 0 || z.value >= m.index.zone_count()) {
      return Status(StatusCode::kInvalidArgument,
                    "route names zone " + std::to_string(z.value) + "; zones are 0.." +
                        std::to_string(m.index.zone_count() - 1));
    }
  }
  m.route.assign(route.begin(), route.end());
  m.decide->SetRoute(m.route);
  return Status::Ok();
}

std::string_view ZoneManager::policy() const { return impl_->decide->policy().name(); }
std::uint32_t ZoneManager::k_max() const { return impl_->budget.k_max; }
bool ZoneManager::bounded() const { return impl_->bounded; }
std::uint32_t ZoneManager::keyframe_count() const { return impl_->index.keyframe_count(); }
std::uint32_t ZoneManager::resident_count() const { return impl_->residency->resident_count(); }
bool ZoneManager::IsResident(KeyframeId id) const {
  const zm::KfIndex k = impl_->index.Find(id);
  return k != zm::kNoKf && impl_->residency->IsResident(k);
}
ZoneId ZoneManager::current_zone() const { return impl_->decide->zone(); }
std::int32_t ZoneManager::zone_count() const { return impl_->index.zone_count(); }
std::string_view ZoneManager::zone_name(ZoneId zone) const {
  if (zone.value < 0 || zone.value >= impl_->index.zone_count()) return {};
  return impl_->zones.zone(zone).name;
}
ZoneId ZoneManager::FindZone(std::string_view name) const {
  return impl_->zones.Find(name);
}
std::vector<ZoneMembership> ZoneManager::Memberships() const {
  std::vector<ZoneMembership> out;
  out.reserve(impl_->members.size());
  for (const zm::ZoneMember& z : impl_->members) out.push_back({z.zone, z.keyframe});
  return out;
}
ManagerStats ZoneManager::stats() const { return impl_->stats; }

}  // namespace zonemap
