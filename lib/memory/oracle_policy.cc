// Belady's MIN over zone entries.
#include "memory/oracle_policy.h"

namespace zm {

OraclePolicy::OraclePolicy(const MapIndex& index, const OracleOptions& options)
    : SemanticPolicy(index, SemanticOptions{options.k_max}) {
  for (ZoneId z : options.future) {
    if (z == kNoZone || z.value < 0 || z.value >= index.zone_count()) continue;
    if (!seq_.empty() && seq_.back() == z) continue;
    seq_.push_back(z);
  }
  const auto nz = static_cast<std::size_t>(index.zone_count());
  next_same_.assign(seq_.size(), kNever);
  next_use_.assign(nz, kNever);
  for (std::size_t i = seq_.size(); i-- > 0;) {
    const auto z = static_cast<std::size_t>(seq_[i].value);
    next_same_[i] = next_use_[z];
    next_use_[z] = i;
  }
}

void OraclePolicy::OnEnter(ZoneId z) {
  const std::size_t from = cursor_ == kNever ? 0 : cursor_ + 1;
  for (std::size_t i = from; i < seq_.size(); ++i) {
    if (seq_[i] == z) {
      cursor_ = i;
      next_use_[static_cast<std::size_t>(z.value)] = next_same_[i];
      return;
    }
  }
  // Not in the remaining future: it will not be needed again as far as we know.
  next_use_[static_cast<std::size_t>(z.value)] = kNever;
}

std::size_t OraclePolicy::NextUse(ZoneId z) {
  std::size_t& n = next_use_[static_cast<std::size_t>(z.value)];
  while (n != kNever && cursor_ != kNever && n <= cursor_) n = next_same_[n];
  return n;
}

ZoneId OraclePolicy::SelectUnloadZone(ZoneId z_new) {
  ZoneId victim = kNoZone;
  std::size_t farthest = 0;
  bool first = true;
  for (ZoneId z : residency_.active_zones()) {
    if (z == z_new) continue;
    const std::size_t next = NextUse(z);  // kNever is the largest value: evicted first
    if (first || next > farthest || (next == farthest && z < victim)) {
      farthest = next;
      victim = z;
      first = false;
    }
  }
  return victim;
}

}  // namespace zm
