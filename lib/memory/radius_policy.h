// RadiusPolicy: Autoware-style dynamic map loading (ndt_scan_matcher dynamic_map_loading with
// pointcloud_map_loader's differential loading). The map is cut into fixed square tiles
// (tile_m, 20 m as pointcloud_divider's default grid); whenever the robot has moved
// update_distance_m (20 m) since the last update, the tiles overlapping a circle of
// map_radius_m around it are wanted and every other tile is evicted.
//
// Unlike Autoware, a budget holds: tiles are taken nearest first (distance from the robot to
// the tile's rectangle) while they fit in k_max; the first tile that does not fit is filled
// nearest-keyframe-first up to the budget, and the rest of the circle is left out. Tiles are
// not stored in the database, so a load is one per-keyframe batch (LoadKeyframes).
//
// Invariants: resident <= k_max after every update (unloads precede loads); no allocation
// after construction.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "memory/policy.h"

namespace zm {

class RadiusPolicy final : public MemoryPolicy {
 public:
  RadiusPolicy(const MapIndex& index, RadiusOptions options);
  [[nodiscard]] std::string_view name() const override { return "radius"; }
  void Start(const TickContext& ctx, Plan* plan) override;
  void PlanBeforeLocalize(const TickContext& ctx, Plan* plan) override;
  void PlanAfterLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  // Redoes the last update (same centre) within k_max: the wanted set is then a subset of what
  // is resident (tiles nearest first, the partial tile nearest-first), so releases only.
  void ChangeBudget(std::uint32_t k_max, const TickContext& ctx, Plan* plan) override;

  [[nodiscard]] std::uint32_t resident() const { return static_cast<std::uint32_t>(resident_list_.size()); }
  [[nodiscard]] std::uint64_t updates() const { return updates_; }
  [[nodiscard]] std::int64_t TileOf(KfIndex k) const { return tile_of_[k]; }

 private:
  void Update(const Eigen::Vector3d& p, Plan* plan);

  const MapIndex& index_;
  RadiusOptions options_;
  double tile_m_;
  std::int64_t tiles_x_ = 1, tiles_y_ = 1;
  std::vector<std::int64_t> tile_of_;          // per keyframe
  std::vector<std::uint32_t> tile_offsets_;    // CSR tile -> keyframes
  std::vector<KfIndex> tile_items_;
  std::vector<std::uint8_t> resident_;         // per keyframe
  std::vector<KfIndex> resident_list_;
  std::vector<std::uint32_t> resident_pos_;
  std::vector<std::uint32_t> want_;            // per keyframe: == epoch_ when wanted
  std::uint32_t epoch_ = 0;
  std::vector<std::pair<double, std::int64_t>> tiles_;  // scratch: (distance, tile)
  std::vector<std::pair<double, KfIndex>> partial_;     // scratch: one tile's keyframes
  std::vector<KfIndex> wanted_;                         // scratch
  bool updated_once_ = false;
  Eigen::Vector3d last_update_ = Eigen::Vector3d::Zero();
  std::uint64_t updates_ = 0;
};

}  // namespace zm
