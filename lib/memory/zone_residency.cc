// ZoneResidency: union counting over overlapping zones.
#include "memory/zone_residency.h"

#include <algorithm>
#include <cassert>

namespace zm {

ZoneResidency::ZoneResidency(const MapIndex& index) : index_(index) {
  held_.assign(index.keyframe_count(), 0);
  mark_.assign(index.keyframe_count(), 0);
  held_members_.assign(index.total_memberships(), kNoKf);
  const auto nz = static_cast<std::size_t>(index.zone_count());
  held_count_.assign(nz, 0);
  active_.assign(nz, 0);
  active_list_.reserve(nz);
}

std::uint32_t ZoneResidency::MarkAndCountNew(std::span<const KfIndex> members) {
  if (++epoch_ == 0) {  // wrapped: forget every old mark
    std::fill(mark_.begin(), mark_.end(), 0U);
    epoch_ = 1;
  }
  std::uint32_t fresh = 0;
  for (KfIndex k : members) {
    if (mark_[k] == epoch_) continue;
    mark_[k] = epoch_;
    if (held_[k] == 0) ++fresh;
  }
  return fresh;
}

std::uint32_t ZoneResidency::Evict(ZoneId z, Plan* plan) {
  if (active_[U(z)] == 0) return 0;
  std::uint32_t freed = 0;
  for (KfIndex k : held_members(z)) {
    plan->Release(k);
    assert(held_[k] > 0);
    if (--held_[k] == 0) {
      --resident_;
      if (mark_[k] != epoch_) ++freed;
    }
  }
  held_count_[U(z)] = 0;
  active_[U(z)] = 0;
  auto it = std::find(active_list_.begin(), active_list_.end(), z);
  if (it != active_list_.end()) {
    *it = active_list_.back();
    active_list_.pop_back();
  }
  plan->NoteZoneUnloaded(z);
  return freed;
}

std::uint32_t ZoneResidency::Hold(ZoneId z, std::span<const KfIndex> members, Plan* plan) {
  if (active_[U(z)] == 0) {
    active_[U(z)] = 1;
    active_list_.push_back(z);
    plan->NoteZoneLoaded(z);
  }
  if (members.empty()) return 0;
  plan->BeginBatch(z);
  std::uint32_t added = 0;
  KfIndex* seg = held_members_.data() + index_.ZoneOffset(z);
  for (KfIndex k : members) {
    assert(held_count_[U(z)] < index_.ZoneSize(z));
    seg[held_count_[U(z)]++] = k;
    plan->Acquire(k);
    if (held_[k]++ == 0) {
      ++resident_;
      ++added;
    }
  }
  return added;
}

}  // namespace zm
