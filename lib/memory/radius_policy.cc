// Distance tiles around the robot, nearest first within the budget.
#include "memory/radius_policy.h"

#include <algorithm>
#include <cmath>

namespace zm {

RadiusPolicy::RadiusPolicy(const MapIndex& index, RadiusOptions options)
    : index_(index), options_(options), tile_m_(options.tile_m > 0 ? options.tile_m : 20.0) {
  const std::size_t n = index.keyframe_count();
  const Eigen::Vector2d extent = index.bbox_max() - index.bbox_min();
  // Keep the tile table bounded on huge sparse maps by growing the tile.
  while ((extent.x() / tile_m_ + 1.0) * (extent.y() / tile_m_ + 1.0) > 4.0e6) tile_m_ *= 2.0;
  tiles_x_ = static_cast<std::int64_t>(std::floor(extent.x() / tile_m_)) + 1;
  tiles_y_ = static_cast<std::int64_t>(std::floor(extent.y() / tile_m_)) + 1;
  const auto tiles = static_cast<std::size_t>(tiles_x_ * tiles_y_);
  tile_of_.assign(n, 0);
  tile_offsets_.assign(tiles + 1, 0);
  for (KfIndex k = 0; k < n; ++k) {
    const Eigen::Vector2d rel = index.position(k).head<2>() - index.bbox_min();
    const auto tx = static_cast<std::int64_t>(std::floor(rel.x() / tile_m_));
    const auto ty = static_cast<std::int64_t>(std::floor(rel.y() / tile_m_));
    tile_of_[k] = ty * tiles_x_ + tx;
    ++tile_offsets_[static_cast<std::size_t>(tile_of_[k])];
  }
  std::uint32_t run = 0;
  for (auto& c : tile_offsets_) {
    const std::uint32_t here = c;
    c = run;
    run += here;
  }
  tile_items_.resize(n);
  std::vector<std::uint32_t> fill(tile_offsets_.begin(), tile_offsets_.end() - 1);
  for (KfIndex k = 0; k < n; ++k) tile_items_[fill[static_cast<std::size_t>(tile_of_[k])]++] = k;
  resident_.assign(n, 0);
  resident_list_.reserve(n);
  resident_pos_.assign(n, 0);
  want_.assign(n, 0);
  tiles_.reserve(tiles);
  std::uint32_t biggest = 0;
  for (std::size_t t = 0; t < tiles; ++t) biggest = std::max(biggest, tile_offsets_[t + 1] - tile_offsets_[t]);
  partial_.reserve(biggest);
  wanted_.reserve(n);
}

void RadiusPolicy::Start(const TickContext& ctx, Plan* plan) { PlanBeforeLocalize(ctx, plan); }

void RadiusPolicy::PlanBeforeLocalize(const TickContext& ctx, Plan* plan) {
  const Eigen::Vector3d p = ctx.pose.translation();
  if (updated_once_ && (p - last_update_).head<2>().norm() < options_.update_distance_m) return;
  updated_once_ = true;
  last_update_ = p;
  Update(p, plan);
}

void RadiusPolicy::Update(const Eigen::Vector3d& p, Plan* plan) {
  ++updates_;
  if (++epoch_ == 0) {
    std::fill(want_.begin(), want_.end(), 0U);
    epoch_ = 1;
  }
  // Tiles overlapping the circle, by distance from the robot to the tile rectangle.
  const double r = options_.map_radius_m;
  const Eigen::Vector2d rel = p.head<2>() - index_.bbox_min();
  const auto clamp_x = [&](double v) {
    return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(v / tile_m_)), 0, tiles_x_ - 1);
  };
  const auto clamp_y = [&](double v) {
    return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(v / tile_m_)), 0, tiles_y_ - 1);
  };
  tiles_.clear();
  for (std::int64_t ty = clamp_y(rel.y() - r); ty <= clamp_y(rel.y() + r); ++ty) {
    for (std::int64_t tx = clamp_x(rel.x() - r); tx <= clamp_x(rel.x() + r); ++tx) {
      const auto t = static_cast<std::size_t>(ty * tiles_x_ + tx);
      if (tile_offsets_[t + 1] == tile_offsets_[t]) continue;  // empty tile
      const double x0 = static_cast<double>(tx) * tile_m_, y0 = static_cast<double>(ty) * tile_m_;
      const double dx = std::max({x0 - rel.x(), 0.0, rel.x() - (x0 + tile_m_)});
      const double dy = std::max({y0 - rel.y(), 0.0, rel.y() - (y0 + tile_m_)});
      const double d = std::hypot(dx, dy);
      if (d <= r) tiles_.emplace_back(d, static_cast<std::int64_t>(t));
    }
  }
  std::sort(tiles_.begin(), tiles_.end());
  // Whole tiles while they fit; the first that does not is filled nearest-first; then stop.
  std::uint32_t budget = options_.k_max;
  wanted_.clear();
  for (const auto& [d, t] : tiles_) {
    const auto tu = static_cast<std::size_t>(t);
    const std::uint32_t size = tile_offsets_[tu + 1] - tile_offsets_[tu];
    if (size <= budget) {
      for (std::uint32_t i = tile_offsets_[tu]; i < tile_offsets_[tu + 1]; ++i) {
        want_[tile_items_[i]] = epoch_;
        wanted_.push_back(tile_items_[i]);
      }
      budget -= size;
      continue;
    }
    partial_.clear();
    for (std::uint32_t i = tile_offsets_[tu]; i < tile_offsets_[tu + 1]; ++i) {
      const KfIndex k = tile_items_[i];
      partial_.emplace_back((index_.position(k) - p).squaredNorm(), k);
    }
    std::sort(partial_.begin(), partial_.end());
    for (std::uint32_t i = 0; i < budget; ++i) {
      want_[partial_[i].second] = epoch_;
      wanted_.push_back(partial_[i].second);
    }
    break;
  }
  // Evict everything not wanted, then load what is wanted and missing.
  for (std::size_t i = resident_list_.size(); i-- > 0;) {
    const KfIndex k = resident_list_[i];
    if (want_[k] == epoch_) continue;
    plan->Release(k);
    resident_[k] = 0;
    resident_list_[i] = resident_list_.back();
    resident_pos_[resident_list_[i]] = static_cast<std::uint32_t>(i);
    resident_list_.pop_back();
  }
  bool begun = false;
  for (KfIndex k : wanted_) {
    if (resident_[k] != 0) continue;
    if (!begun) {
      plan->BeginBatch(kNoZone);
      begun = true;
    }
    plan->Acquire(k);
    resident_[k] = 1;
    resident_pos_[k] = static_cast<std::uint32_t>(resident_list_.size());
    resident_list_.push_back(k);
  }
}


void RadiusPolicy::ChangeBudget(std::uint32_t k_max, const TickContext& /*ctx*/, Plan* plan) {
  options_.k_max = k_max;
  if (updated_once_ && resident() > k_max) Update(last_update_, plan);
}

}  // namespace zm
