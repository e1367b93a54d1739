// ExternalWorkingSet::Apply: reference counts in the plan's order, then the net lists.
#include "memory/external_working_set.h"

#include <algorithm>
#include <limits>
#include <string>

namespace zm {
namespace {

// before_count_ value of a keyframe already written to one of the lists in this Apply.
constexpr std::uint32_t kEmitted = std::numeric_limits<std::uint32_t>::max();

}  // namespace

ExternalWorkingSet::ExternalWorkingSet(const MapIndex& index) : index_(index) {
  const std::size_t n = index.keyframe_count();
  refcount_.assign(n, 0);
  before_count_.assign(n, 0);
  touched_.assign(n, 0);
  unloads_.reserve(n);
  loads_.reserve(n);
  // The same bound as Plan::Reserve's batch buffer: a plan never has more batches.
  batches_.reserve((static_cast<std::size_t>(index.zone_count()) + 2) * 2);
}

void ExternalWorkingSet::Touch(KfIndex k) {
  if (touched_[k] == epoch_) return;
  touched_[k] = epoch_;
  before_count_[k] = refcount_[k];
}

Status ExternalWorkingSet::ApplyReleases(const Plan& plan) {
  for (KfIndex k : plan.releases()) {
    if (refcount_[k] == 0) {
      return Internal("plan releases keyframe " + std::to_string(index_.id(k).value) +
                      ", which nobody holds (a policy bug)");
    }
    --refcount_[k];
  }
  return Status::Ok();
}

void ExternalWorkingSet::ApplyAcquires(const Plan& plan) {
  for (KfIndex k : plan.acquires()) ++refcount_[k];
}

Status ExternalWorkingSet::Apply(const Plan& plan) {
  unloads_.clear();
  loads_.clear();
  batches_.clear();
  if (++epoch_ == 0) {  // wrapped after 2^32 applies: forget every old mark
    std::fill(touched_.begin(), touched_.end(), 0U);
    epoch_ = 1;
  }
  for (KfIndex k : plan.releases()) Touch(k);
  for (KfIndex k : plan.acquires()) Touch(k);
  before_ = resident_;

  Status s;
  if (plan.order == PlanOrder::kUnloadThenLoad) {
    s = ApplyReleases(plan);
    if (s.ok()) ApplyAcquires(plan);
  } else {
    ApplyAcquires(plan);
    s = ApplyReleases(plan);
  }
  if (!s.ok()) {
    // Every count the plan touched goes back to what it was: the host's view is unchanged.
    for (KfIndex k : plan.releases()) refcount_[k] = before_count_[k];
    for (KfIndex k : plan.acquires()) refcount_[k] = before_count_[k];
    peak_ = before_;
    return s;
  }

  for (KfIndex k : plan.releases()) {
    if (before_count_[k] != kEmitted && before_count_[k] > 0 && refcount_[k] == 0) {
      unloads_.push_back(k);
      before_count_[k] = kEmitted;
    }
  }
  const auto acquires = plan.acquires();
  for (const PlanBatch& b : plan.batches()) {
    const auto begin = static_cast<std::uint32_t>(loads_.size());
    for (std::uint32_t i = b.begin; i < b.end; ++i) {
      const KfIndex k = acquires[i];
      if (before_count_[k] == 0 && refcount_[k] > 0) {
        loads_.push_back(k);
        before_count_[k] = kEmitted;
      }
    }
    const auto end = static_cast<std::uint32_t>(loads_.size());
    if (end > begin && batches_.size() < batches_.capacity()) {
      batches_.push_back(LoadBatch{b.zone, begin, end});
    } else if (end > begin) {
      batches_.back().end = end;  // cannot happen (a plan has no more batches than reserved)
    }
  }
  resident_ = before_ - static_cast<std::uint32_t>(unloads_.size()) +
              static_cast<std::uint32_t>(loads_.size());
  peak_ = std::max(before_, resident_);
  max_seen_ = std::max(max_seen_, peak_);
  return Status::Ok();
}

}  // namespace zm
