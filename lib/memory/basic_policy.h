// BasicPolicy: RTAB-Map's default memory management in localization mode, following rules
// 1-12 of the "Baseline spec for re-implementation" in basic-baseline.md (RTAB-Map v0.23.8).
//
// Per tick, after localization (PlanAfterLocalize), in RTAB-Map's order:
//   retrieval  - local: L nodes within LocalRadius of the pose, nearest first, add their
//                one-hop LTM neighbours (<= MaxLocalRetrieved) and immunize up to
//                int(0.25 |WM|) of them; refresh their ages;
//              - global: from the highest hypothesis, a time search (neighbour links, margins
//                0..16, <= MaxRetrieved LTM nodes admitted, all returned ids immunized) and a
//                space search (all links, loop links add a margin, ids appended, not immunized);
//              - load the first MaxRetrieved + |local| ids not in WM, one per-keyframe batch;
//   local map  - L becomes the WM component of the localization node when the frame is
//                localized and retrieved something or localized outside L;
//   transfer   - if |WM| > MemoryThr: exactly retrieved + 1 nodes leave WM, smallest
//                (weight, floor(age_s), id) first among the non-immunized; never in bulk.
// Its plan loads before it unloads (PlanOrder::kLoadThenUnload), so like RTAB-Map it can sit
// above MemoryThr: by retrieved nodes within a tick, and for N - MemoryThr ticks after an
// oversized start-up WM. The WorkingSet's arena must therefore be larger than MemoryThr; the
// over-budget telemetry measures by how much and for how long.
//
// Simplifications, all inert on zonemap maps: no STM (localization mode keeps only the frame,
// which has no links), intermediate nodes (weight -1) are excluded from WM size and transfer
// but expanded like normal nodes, TimeThr is not modelled (MemoryThr only).
//
// Graph searches: nodes in WM are expanded from the MapIndex (RAM, as RTAB-Map holds them);
// each LTM node a search admits is read through the LtmGraph given at construction, its weight
// and links, and the search goes on with what that read returned. With the run-time's
// SourceLtmGraph that is the map database, two statements per node (rule 11), accounted in
// Plan::search; an LTM node whose read fails is treated as not admitted and the error is
// reported through the plan.
//
// Invariant: no allocation per tick once constructed (every scratch buffer is sized from N).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "memory/ltm_graph.h"
#include "memory/policy.h"

namespace zm {

class BasicPolicy final : public MemoryPolicy {
 public:
  // `ltm` reads long-term-memory nodes (the run-time passes the map's SourceLtmGraph; it must
  // outlive the policy); null = the MapIndex stands in for the database (IndexLtmGraph).
  BasicPolicy(const MapIndex& index, BasicOptions options, LtmGraph* ltm = nullptr);

  [[nodiscard]] std::string_view name() const override { return "basic"; }
  void Start(const TickContext& ctx, Plan* plan) override;
  void PlanBeforeLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  void PlanAfterLocalize(const TickContext& ctx, Plan* plan) override;

  // What the last PlanAfterLocalize did (for telemetry and tests).
  struct TickReport {
    std::vector<KfIndex> retrieved;    // loaded this tick, in load order
    std::vector<KfIndex> transferred;  // left WM this tick, in transfer order
    std::uint32_t local_retrieved = 0; // |local| (the quota user)
    std::uint32_t max_local_imm = 0;
    std::uint32_t immunized = 0;
    std::uint32_t wm_size = 0;         // after the transfer (Memory/Working_memory_size)
    std::uint32_t search_queries = 0;  // statements its searches executed (2 per LTM node read)
  };
  [[nodiscard]] const TickReport& last_tick() const { return report_; }
  [[nodiscard]] std::uint32_t wm_size() const { return wm_count_; }
  [[nodiscard]] bool InWm(KfIndex k) const { return in_wm_[k] != 0; }
  [[nodiscard]] bool InLocalMap(KfIndex k) const { return in_local_[k] != 0; }
  [[nodiscard]] std::uint32_t local_map_size() const { return local_count_; }
  [[nodiscard]] KfIndex last_localization() const { return last_loc_; }
  [[nodiscard]] bool all_in_wm() const { return all_in_wm_; }
  [[nodiscard]] double age_s(KfIndex k) const { return age_s_[k]; }

 private:
  struct Found {
    KfIndex k = kNoKf;
    std::uint32_t margin = 0;
    std::int32_t weight = 0;  // WM: from RAM; LTM: as read through ltm_
  };
  // getNeighborsId: breadth-first over margins 0..max_depth-1 from `start`; WM nodes are free,
  // LTM nodes admitted (read through ltm_) while fewer than max_ltm non-intermediate ones were.
  // Fills found_ in visit order: margin ascending, id descending within a margin.
  void Neighbors(KfIndex start, std::uint32_t max_depth, std::uint32_t max_ltm, bool ignore_loops);
  void AddToWm(KfIndex k, double now_s);
  void RemoveFromWm(KfIndex k);
  // L = WM component containing `from` (intersected with the old L if `intersect`).
  void RebuildLocalMap(KfIndex from, bool intersect);
  bool Immunized(KfIndex k) const { return immune_[k] == tick_epoch_; }
  void Immunize(KfIndex k);
  bool InReactivated(KfIndex k) const { return react_mark_[k] == tick_epoch_; }
  void AppendReactivated(KfIndex k);
  void Transfer(std::uint32_t count, Plan* plan);
  void NextEpoch();

  const MapIndex& index_;
  BasicOptions options_;
  IndexLtmGraph index_graph_;  // used when no LtmGraph is given
  LtmGraph* ltm_;
  LoadStats search_;     // this tick's search reads
  Status search_error_;  // this tick's first failed read
  std::vector<std::uint8_t> in_wm_;
  std::vector<double> age_s_;
  std::vector<KfIndex> wm_list_;
  std::vector<std::uint32_t> wm_pos_;
  std::uint32_t wm_count_ = 0;  // excludes weight -1
  std::vector<std::uint8_t> in_local_;
  std::uint32_t local_count_ = 0;
  KfIndex last_loc_ = kNoKf;
  bool all_in_wm_ = false;
  KfIndex prev_highest_ = kNoKf;
  bool prev_localized_ = false;

  std::uint32_t tick_epoch_ = 0;
  std::vector<std::uint32_t> immune_;      // == tick_epoch_: immunized this tick
  std::uint32_t immune_count_ = 0;
  std::vector<std::uint32_t> react_mark_;  // == tick_epoch_: in reactivated_
  std::vector<KfIndex> reactivated_;
  std::vector<KfIndex> local_;             // local retrieval ids (LTM), in order
  std::vector<KfIndex> local_inter_;
  // Search scratch.
  std::uint32_t search_epoch_ = 0;
  std::vector<std::uint32_t> seen_;        // == search_epoch_: queued or found in this search
  std::vector<Found> found_;
  std::vector<KfIndex> margin_, next_margin_;
  std::vector<std::pair<double, KfIndex>> near_;
  std::vector<KfIndex> queue_;
  std::vector<std::uint32_t> comp_mark_;
  std::uint32_t comp_epoch_ = 0;
  std::vector<KfIndex> candidates_;        // transfer: the smallest keys so far
  TickReport report_;
};

}  // namespace zm
