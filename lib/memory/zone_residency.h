// ZoneResidency: the bookkeeping shared by the zone-level policies (semantic, oracle,
// predictive). Tracks the active zone set A, which members each active zone holds (all of them,
// or a nearest-first / time-sliced part), and per keyframe how many active zones hold it, so
// predicted counts are unions: a keyframe held by two zones is counted once, freed only when
// the last holder goes, and not re-read when a new zone shares it.
//
// Invariants:
//   - held(k) = number of active zones whose held part contains k; resident() = |{k: held>0}|;
//   - every Hold/Evict writes the matching Acquire/Release references into the plan, so the
//     WorkingSet's reference counts equal held() after Apply;
//   - all storage is sized at construction (CSR-shaped like the MapIndex's zone members);
//     nothing allocates afterwards.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "memory/map_index.h"
#include "memory/plan.h"

namespace zm {

class ZoneResidency {
 public:
  explicit ZoneResidency(const MapIndex& index);

  [[nodiscard]] bool active(ZoneId z) const { return active_[U(z)] != 0; }
  [[nodiscard]] std::span<const ZoneId> active_zones() const { return active_list_; }
  [[nodiscard]] std::uint32_t resident() const { return resident_; }
  [[nodiscard]] std::uint32_t held(KfIndex k) const { return held_[k]; }
  // Members of z currently held by z (a prefix of what Hold() was given, in that order).
  [[nodiscard]] std::span<const KfIndex> held_members(ZoneId z) const {
    return {held_members_.data() + index_.ZoneOffset(z), held_count_[U(z)]};
  }

  // Marks `members` with a fresh epoch and returns how many of them no active zone holds:
  // the keyframes a load of them would newly need. Evict() consults the marks.
  std::uint32_t MarkAndCountNew(std::span<const KfIndex> members);
  // Deactivates z: releases every member it holds. Returns how many keyframes stop being
  // resident that are not marked by the last MarkAndCountNew (i.e. the K_pred decrease).
  std::uint32_t Evict(ZoneId z, Plan* plan);
  // Makes z active (if it is not) and adds `members` (members of z not yet held by z) to its
  // held part, as one batch of z. Returns how many keyframes became resident.
  std::uint32_t Hold(ZoneId z, std::span<const KfIndex> members, Plan* plan);

 private:
  static std::size_t U(ZoneId z) { return static_cast<std::size_t>(z.value); }

  const MapIndex& index_;
  std::vector<std::uint32_t> held_;         // per keyframe
  std::vector<std::uint32_t> mark_;         // per keyframe: epoch of the last MarkAndCountNew
  std::uint32_t epoch_ = 0;
  std::vector<KfIndex> held_members_;       // per zone segment (zone CSR layout)
  std::vector<std::uint32_t> held_count_;   // per zone
  std::vector<std::uint8_t> active_;        // per zone
  std::vector<ZoneId> active_list_;         // reserved to zone_count
  std::uint32_t resident_ = 0;
};

}  // namespace zm
