// RTAB-Map's retrieval/transfer (basic-baseline.md rules 1-12). Source references are to
// RTAB-Map v0.23.8 (R.cpp = Rtabmap.cpp, M.cpp = Memory.cpp), as in the baseline document.
#include "memory/basic_policy.h"

#include <algorithm>
#include <cassert>
#include <tuple>

namespace zm {
namespace {

bool IsNeighborLink(LinkKind t) {
  return t == LinkKind::kNeighbor || t == LinkKind::kNeighborMerged;
}

}  // namespace

BasicPolicy::BasicPolicy(const MapIndex& index, BasicOptions options, LtmGraph* ltm)
    : index_(index),
      options_(std::move(options)),
      index_graph_(index),
      ltm_(ltm != nullptr ? ltm : &index_graph_) {
  const std::size_t n = index.keyframe_count();
  in_wm_.assign(n, 0);
  age_s_.assign(n, 0.0);
  wm_list_.reserve(n);
  wm_pos_.assign(n, 0);
  in_local_.assign(n, 0);
  immune_.assign(n, 0);
  react_mark_.assign(n, 0);
  reactivated_.reserve(n);
  local_.reserve(n);
  local_inter_.reserve(n);
  seen_.assign(n, 0);
  found_.reserve(n);
  margin_.reserve(n);
  next_margin_.reserve(n);
  near_.reserve(n);
  queue_.reserve(n);
  comp_mark_.assign(n, 0);
  const std::size_t most = options_.max_retrieved + options_.max_local_retrieved + 2;
  candidates_.reserve(most);
  report_.retrieved.reserve(n);  // start-up can retrieve everything
  report_.transferred.reserve(most);
}

void BasicPolicy::NextEpoch() {
  if (++tick_epoch_ == 0) {
    std::fill(immune_.begin(), immune_.end(), 0U);
    std::fill(react_mark_.begin(), react_mark_.end(), 0U);
    tick_epoch_ = 1;
  }
  immune_count_ = 0;
}

void BasicPolicy::Immunize(KfIndex k) {
  if (immune_[k] != tick_epoch_) {
    immune_[k] = tick_epoch_;
    ++immune_count_;
  }
}

void BasicPolicy::AppendReactivated(KfIndex k) {
  if (react_mark_[k] == tick_epoch_) return;
  react_mark_[k] = tick_epoch_;
  reactivated_.push_back(k);
}

void BasicPolicy::AddToWm(KfIndex k, double now_s) {
  if (in_wm_[k] != 0) return;
  in_wm_[k] = 1;
  age_s_[k] = now_s;
  wm_pos_[k] = static_cast<std::uint32_t>(wm_list_.size());
  wm_list_.push_back(k);
  if (index_.weight(k) != -1) ++wm_count_;
}

void BasicPolicy::RemoveFromWm(KfIndex k) {
  if (in_wm_[k] == 0) return;
  in_wm_[k] = 0;
  const std::uint32_t pos = wm_pos_[k];
  wm_list_[pos] = wm_list_.back();
  wm_pos_[wm_list_[pos]] = pos;
  wm_list_.pop_back();
  if (index_.weight(k) != -1) --wm_count_;
  if (in_local_[k] != 0) {
    in_local_[k] = 0;
    --local_count_;
  }
}

void BasicPolicy::Start(const TickContext& ctx, Plan* plan) {
  NextEpoch();
  report_.retrieved.clear();
  report_.transferred.clear();
  // Rule 2: WM = all valid nodes, or the last session's WM; age = load time.
  plan->order = PlanOrder::kLoadThenUnload;
  plan->BeginBatch(kNoZone);
  auto admit = [&](KfIndex k) {
    if (k == kNoKf || in_wm_[k] != 0 || index_.weight(k) <= -9) return;
    AddToWm(k, ctx.now_s);
    plan->Acquire(k);
    report_.retrieved.push_back(k);
  };
  if (options_.init_wm_with_all_nodes) {
    for (KfIndex k = 0; k < index_.keyframe_count(); ++k) admit(k);
  } else {
    for (KeyframeId id : options_.initial_wm) admit(index_.Find(id));
  }
  // allInWM: every link of every loaded node points to a loaded node (M.cpp:330-343).
  all_in_wm_ = true;
  for (KfIndex k : wm_list_) {
    for (const GraphEdge& e : index_.Edges(k)) {
      if (in_wm_[e.to] == 0) all_in_wm_ = false;
    }
  }
  // lastLoc = the WM node nearest to the start pose; L = its WM component.
  const Eigen::Vector3d p = ctx.pose.translation();
  double best = 0.0;
  for (KfIndex k : wm_list_) {
    const double d = (index_.position(k) - p).squaredNorm();
    if (last_loc_ == kNoKf || d < best) {
      best = d;
      last_loc_ = k;
    }
  }
  if (last_loc_ != kNoKf) RebuildLocalMap(last_loc_, false);
  report_.wm_size = wm_count_;
}

void BasicPolicy::Neighbors(KfIndex start, std::uint32_t max_depth, std::uint32_t max_ltm,
                            bool ignore_loops) {
  if (++search_epoch_ == 0) {
    std::fill(seen_.begin(), seen_.end(), 0U);
    search_epoch_ = 1;
  }
  found_.clear();
  next_margin_.clear();
  next_margin_.push_back(start);
  seen_[start] = search_epoch_;
  std::uint32_t admitted_ltm = 0;
  for (std::uint32_t m = 0; (max_depth == 0 || m < max_depth) && !next_margin_.empty(); ++m) {
    std::swap(margin_, next_margin_);
    next_margin_.clear();
    // Within a margin, more recent (larger) ids first (M.cpp:1738-1739).
    std::sort(margin_.begin(), margin_.end(),
              [&](KfIndex a, KfIndex b) { return index_.id(a) > index_.id(b); });
    for (KfIndex n : margin_) {
      std::int32_t weight = index_.weight(n);
      std::span<const GraphEdge> edges = index_.Edges(n);
      if (in_wm_[n] == 0) {
        // LTM: admitted only under the limit, then read (getWeight, loadLinks: M.cpp:1772-1813)
        // and expanded along the links that read returned.
        if (admitted_ltm >= max_ltm) {
          seen_[n] = 0;  // may be reached again by another path, and refused again
          continue;
        }
        LtmNode node;
        Status read = ltm_->Read(n, &node, &search_);
        if (!read.ok()) {
          if (search_error_.ok()) search_error_ = std::move(read);
          seen_[n] = 0;
          continue;
        }
        weight = node.weight;
        edges = node.edges;
        if (weight != -1) ++admitted_ltm;
      }
      found_.push_back(Found{n, m, weight});
      for (const GraphEdge& e : edges) {
        if (seen_[e.to] == search_epoch_) continue;
        if (!IsNeighborLink(e.type)) {
          if (ignore_loops) continue;
          // incrementMarginOnLoop is true in every call basic makes: next margin.
        }
        seen_[e.to] = search_epoch_;
        next_margin_.push_back(e.to);
      }
    }
  }
}

void BasicPolicy::RebuildLocalMap(KfIndex from, bool intersect) {
  if (++comp_epoch_ == 0) {
    std::fill(comp_mark_.begin(), comp_mark_.end(), 0U);
    comp_epoch_ = 1;
  }
  queue_.clear();
  if (from != kNoKf && in_wm_[from] != 0) {
    queue_.push_back(from);
    comp_mark_[from] = comp_epoch_;
  }
  for (std::size_t i = 0; i < queue_.size(); ++i) {
    for (const GraphEdge& e : index_.Edges(queue_[i])) {
      if (in_wm_[e.to] != 0 && comp_mark_[e.to] != comp_epoch_) {
        comp_mark_[e.to] = comp_epoch_;
        queue_.push_back(e.to);
      }
    }
  }
  // New L: the component (intersected with the old L when pruning after a transfer).
  local_count_ = 0;
  for (KfIndex k : wm_list_) {
    const bool in_comp = comp_mark_[k] == comp_epoch_;
    const bool keep = intersect ? (in_comp && in_local_[k] != 0) : in_comp;
    in_local_[k] = keep ? 1 : 0;
    local_count_ += keep ? 1U : 0U;
  }
  if (intersect && (from == kNoKf || in_local_[from] == 0)) {  // lastLoc not in L: clear L
    for (KfIndex k : wm_list_) in_local_[k] = 0;
    local_count_ = 0;
  }
}

void BasicPolicy::Transfer(std::uint32_t count, Plan* plan) {
  // Rule 8: repeatedly the minimum of (weight, floor(age), id) over WM \ immunized, weight >= 0.
  // One pass keeps the `count` smallest keys (count <= MaxRetrieved + MaxLocalRetrieved + 1).
  auto key = [&](KfIndex k) {
    const auto age = options_.transfer_sorting_by_weight_id
                         ? std::int64_t{0}
                         : static_cast<std::int64_t>(age_s_[k]);  // the int cast of M.cpp:2622
    return std::make_tuple(index_.weight(k), age, index_.id(k));
  };
  candidates_.clear();
  for (KfIndex k : wm_list_) {
    if (Immunized(k) || index_.weight(k) < 0) continue;
    if (candidates_.size() == count && !(key(k) < key(candidates_.back()))) continue;
    if (candidates_.size() == count) candidates_.pop_back();
    auto at = std::upper_bound(candidates_.begin(), candidates_.end(), k,
                               [&](KfIndex a, KfIndex b) { return key(a) < key(b); });
    candidates_.insert(at, k);
  }
  for (KfIndex k : candidates_) {
    RemoveFromWm(k);
    plan->Release(k);
    report_.transferred.push_back(k);
  }
  if (!candidates_.empty()) all_in_wm_ = false;
}

void BasicPolicy::PlanAfterLocalize(const TickContext& ctx, Plan* plan) {
  plan->order = PlanOrder::kLoadThenUnload;
  NextEpoch();
  report_.retrieved.clear();
  report_.transferred.clear();
  report_.local_retrieved = 0;
  report_.search_queries = 0;
  search_ = LoadStats{};
  search_error_ = Status::Ok();
  reactivated_.clear();
  local_.clear();
  local_inter_.clear();
  const double now = ctx.now_s;
  const bool memory_management = options_.memory_thr > 0;
  // Rule 3: computed at the start of the frame, before any retrieval.
  const auto max_local_imm = memory_management
      ? static_cast<std::uint32_t>(options_.local_immunization_ratio * wm_count_)
      : 0U;
  report_.max_local_imm = max_local_imm;

  // The retrieval id: this frame's highest hypothesis, or the last one on a small displacement
  // of a frame localized on the previous one (R.cpp:2229-2231).
  KfIndex highest = ctx.highest_hypothesis.value > 0 ? index_.Find(ctx.highest_hypothesis) : kNoKf;
  if (ctx.small_displacement && prev_localized_) highest = prev_highest_;
  prev_highest_ = highest;

  const bool skip_retrieval =
      (all_in_wm_ || options_.max_retrieved == 0) && max_local_imm == 0;  // R.cpp:2265
  if (!skip_retrieval) {
    // Rule 5: local retrieval and local immunization around the pose, within L.
    const std::uint32_t quota = options_.max_local_retrieved;
    if (!(all_in_wm_ && max_local_imm == 0)) {
      near_.clear();
      index_.ForEachWithin(ctx.pose.translation(), options_.local_radius_m,
                           [&](KfIndex k, double d) {
                             if (in_local_[k] != 0) near_.emplace_back(d, k);
                           });
      std::sort(near_.begin(), near_.end());
      std::uint32_t imm_local = 0;
      // `limit`: how many LTM nodes the search may admit (getNeighborsId's maxCheckedInDatabase).
      auto take_ltm_neighbours = [&](KfIndex from, std::uint32_t limit) {
        Neighbors(from, 2, limit, /*ignore_loops=*/false);
        // Returned ids by descending id; LTM ones join the local list up to the quota.
        std::sort(found_.begin(), found_.end(),
                  [&](const Found& a, const Found& b) { return index_.id(a.k) > index_.id(b.k); });
        for (const Found& f : found_) {
          const KfIndex id = f.k;
          if (local_.size() >= quota) break;
          if (in_wm_[id] != 0 || InReactivated(id)) continue;
          if (f.weight == -1) {
            if (f.margin == 0) local_inter_.push_back(id);
            react_mark_[id] = tick_epoch_;
          } else {
            local_.push_back(id);
            react_mark_[id] = tick_epoch_;
          }
        }
      };
      for (const auto& [d, n] : near_) {
        if (local_.size() >= quota && imm_local >= max_local_imm) break;
        if (index_.weight(n) != -1 && local_.size() < quota) {
          take_ltm_neighbours(n, quota - static_cast<std::uint32_t>(local_.size()));
        }
        if (imm_local < max_local_imm) {
          Immunize(n);
          ++imm_local;
        }
      }
      // Quota not filled: expand one hop from the LTM ids already selected. Each search starts
      // at an LTM node, which is itself read and counts against the limit, so RTAB-Map asks for
      // one more: getNeighborsId(*iter, 2, _maxLocalRetrieved - retrievalLocalIds.size() + 1,
      // true, false) in Rtabmap.cpp's RETRIEVAL 2/3 (basic-baseline.md R.cpp:2602-2632).
      for (std::size_t i = 0; i < local_.size() && local_.size() < quota; ++i) {
        take_ltm_neighbours(local_[i], quota - static_cast<std::uint32_t>(local_.size()) + 1);
      }
      // Ages of the nodes near the pose: now (farthest first; one clock value per tick here).
      for (auto it = near_.rbegin(); it != near_.rend(); ++it) age_s_[it->second] = now;
    }
    for (KfIndex k : local_) reactivated_.push_back(k);
    for (KfIndex k : local_inter_) reactivated_.push_back(k);

    // Rule 4: the neighbourhood of the highest hypothesis.
    if (highest != kNoKf && options_.max_retrieved > 0) {
      const std::uint32_t depth = options_.prediction_lc_size - 1;  // margins 0..16
      Neighbors(highest, depth, options_.max_retrieved, /*ignore_loops=*/true);
      for (const Found& f : found_) {
        Immunize(f.k);  // time search: everything it returns, no budget
        AppendReactivated(f.k);
      }
      Neighbors(highest, depth, options_.max_retrieved, /*ignore_loops=*/false);
      for (const Found& f : found_) AppendReactivated(f.k);  // space search: appended only
    }

    // Rule 6: load the first MaxRetrieved + |local| ids not in RAM, as one batch.
    const auto max_load = options_.max_retrieved + static_cast<std::uint32_t>(local_.size());
    bool begun = false;
    for (KfIndex k : reactivated_) {
      if (report_.retrieved.size() >= max_load) break;
      if (in_wm_[k] != 0) continue;
      if (!begun) {
        plan->BeginBatch(kNoZone);
        begun = true;
      }
      plan->Acquire(k);
      AddToWm(k, now);
      Immunize(k);
      report_.retrieved.push_back(k);
    }
  }
  report_.local_retrieved = static_cast<std::uint32_t>(local_.size());
  report_.search_queries = search_.queries;
  plan->search += search_;
  if (plan->search_error.ok() && !search_error_.ok()) plan->search_error = search_error_;
  const auto retrieved = static_cast<std::uint32_t>(report_.retrieved.size());

  // Rule 10 and 6: localization and the local map.
  const KfIndex loc = ctx.localized_on.value > 0 ? index_.Find(ctx.localized_on) : kNoKf;
  const bool localized = loc != kNoKf && in_wm_[loc] != 0;
  if (localized) {
    const bool outside = in_local_[loc] == 0;
    last_loc_ = loc;
    if (retrieved > 0 || outside) RebuildLocalMap(loc, false);
  }
  prev_localized_ = localized;

  // Rule 7: the transfer, after all other processing.
  if (memory_management && wm_count_ > options_.memory_thr) {
    if (last_loc_ != kNoKf) Immunize(last_loc_);
    Transfer(retrieved + 1, plan);
    // Rule 9: L = L ∩ (WM component of lastLoc); cleared if lastLoc is not in L.
    if (!report_.transferred.empty()) RebuildLocalMap(last_loc_, true);
  }
  report_.immunized = immune_count_;
  report_.wm_size = wm_count_;
}

}  // namespace zm
