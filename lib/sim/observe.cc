// Landmark generation, visibility and noisy features (see observe.h).
#include "sim/observe.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>

#include "localization/camera.h"

namespace zm::sim {

CameraIntrinsics MakeIntrinsics(std::uint32_t width, std::uint32_t height, double hfov_deg) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = (width / 2.0) / std::tan(hfov_deg * std::numbers::pi / 360.0);
  k.fy = k.fx;
  k.cx = width / 2.0;
  k.cy = height / 2.0;
  return k;
}

namespace {

// How far inside its free cell a landmark sits from the face it decorates, in cells (0.02 cell is
// 1 mm at 0.05 m cells: a point from the depth image lands on it).
constexpr double kFaceInset = 0.02;

void RandomDescriptor(Rng& rng, Descriptor256* d) {
  for (std::size_t i = 0; i < kDescriptorBytes; i += 8) {
    const std::uint64_t v = rng.Next();
    for (std::size_t b = 0; b < 8; ++b) (*d)[i + b] = static_cast<std::uint8_t>(v >> (8 * b));
  }
}

// Flips each of the 256 bits with probability p (geometric skips: ~256p draws, not 256).
void FlipBits(Rng& rng, double p, Descriptor256* d) {
  if (p <= 0.0) return;
  const double log_q = std::log1p(-std::min(p, 0.999999));
  long pos = -1;
  while (true) {
    double u = rng.Uniform();
    if (u < 1e-300) u = 1e-300;
    pos += 1 + static_cast<long>(std::floor(std::log(u) / log_q));
    if (pos >= 256) return;
    (*d)[static_cast<std::size_t>(pos / 8)] ^= static_cast<std::uint8_t>(1u << (pos % 8));
  }
}

}  // namespace

LandmarkMap LandmarkMap::Generate(const Building& building, const LandmarkOptions& options,
                                  std::uint64_t seed) {
  LandmarkMap map;
  for (std::size_t f = 0; f < building.floors.size(); ++f) {
    Rng rng(seed, 1000 + f);
    const FloorMap& floor = building.floors[f];
    const SimGrid& g = floor.grid;
    const double res = g.resolution_m;
    const std::size_t first = map.landmarks_.size();
    for (int r = 0; r < g.rows; ++r) {
      for (int c = 0; c < g.cols; ++c) {
        if (!g.Free(c, r)) continue;
        static constexpr int kDc[4] = {1, -1, 0, 0};
        static constexpr int kDr[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; ++k) {
          const int nc = c + kDc[k], nr = r + kDr[k];
          if (g.Free(nc, nr)) continue;  // walls of real maps are often unknown, not occupied
          const bool furniture = g.InBounds(nc, nr) && floor.furniture[g.Index(nc, nr)] != 0;
          const double span = furniture ? building.furniture_height_m : building.wall_height_m;
          const double lambda =
              (furniture ? options.furniture_density_per_m2 : options.wall_density_per_m2) * res * span;
          int n = static_cast<int>(lambda);
          if (rng.Bernoulli(lambda - n)) ++n;
          for (int i = 0; i < n; ++i) {
            const double t = rng.Uniform();
            // Cell-unit position inside the free cell, kFaceInset cell from the shared face: on
            // the wall's surface for the depth camera (which sees the face), yet strictly inside
            // the free cell so the line-of-sight test is well defined.
            double u = c + t, v = r + t;
            if (kDc[k] == 1) u = c + 1.0 - kFaceInset;
            if (kDc[k] == -1) u = c + kFaceInset;
            if (kDr[k] == 1) v = r + 1.0 - kFaceInset;
            if (kDr[k] == -1) v = r + kFaceInset;
            Landmark lm;
            const Eigen::Vector2d xy = g.origin_m + res * Eigen::Vector2d(u, v);
            lm.p = Eigen::Vector3d(xy.x(), xy.y(), floor.z_m + rng.Uniform(0.05, span - 0.05));
            lm.floor = static_cast<int>(f);
            RandomDescriptor(rng, &lm.descriptor);
            map.landmarks_.push_back(lm);
          }
        }
      }
    }
    // Bin this floor's landmarks (counting sort: ids stay in increasing order within a bin).
    FloorIndex idx;
    idx.origin = g.origin_m;
    idx.nx = std::max(1, static_cast<int>(std::ceil(g.width_m() / kBinM)));
    idx.ny = std::max(1, static_cast<int>(std::ceil(g.height_m() / kBinM)));
    const std::size_t nbins = static_cast<std::size_t>(idx.nx) * static_cast<std::size_t>(idx.ny);
    idx.start.assign(nbins + 1, 0);
    const auto bin_of = [&](const Landmark& lm) {
      const int bx = std::clamp(static_cast<int>((lm.p.x() - idx.origin.x()) / kBinM), 0, idx.nx - 1);
      const int by = std::clamp(static_cast<int>((lm.p.y() - idx.origin.y()) / kBinM), 0, idx.ny - 1);
      return static_cast<std::size_t>(by) * static_cast<std::size_t>(idx.nx) + static_cast<std::size_t>(bx);
    };
    for (std::size_t i = first; i < map.landmarks_.size(); ++i) ++idx.start[bin_of(map.landmarks_[i]) + 1];
    for (std::size_t b = 0; b < nbins; ++b) idx.start[b + 1] += idx.start[b];
    idx.ids.resize(map.landmarks_.size() - first);
    std::vector<std::uint32_t> fill(idx.start.begin(), idx.start.end() - 1);
    for (std::size_t i = first; i < map.landmarks_.size(); ++i) {
      idx.ids[fill[bin_of(map.landmarks_[i])]++] = static_cast<std::uint32_t>(i);
    }
    map.index_.push_back(std::move(idx));
  }
  return map;
}

void LandmarkMap::Visible(const Building& building, int floor, const Pose3& t_map_body,
                          const CameraModel& camera, std::vector<VisibleLandmark>* out) const {
  out->clear();
  const auto f = static_cast<std::size_t>(floor);
  if (f >= index_.size()) return;
  const SimGrid& g = building.floors[f].grid;
  const FloorIndex& idx = index_[f];
  const Pose3 t_cam_map = CameraPoseInMap(t_map_body).inverse();
  const Eigen::Vector2d eye = t_map_body.translation().head<2>();
  const double yaw = Yaw(t_map_body);
  const double range = camera.range_m;

  // Coarse occlusion table: wall distance along rays spread over the horizontal FOV. A landmark
  // clearly behind the wall of its own and both neighbouring rays is skipped before the exact test.
  constexpr int kRays = 96;
  const double half_fov = std::atan2(camera.intrinsics.cx, camera.intrinsics.fx) + 0.02;
  double table[kRays];
  for (int i = 0; i < kRays; ++i) {
    const double a = yaw - half_fov + 2.0 * half_fov * (i + 0.5) / kRays;
    table[i] = CastRay(g, eye, Eigen::Vector2d(std::cos(a), std::sin(a)), range);
  }
  const double margin = 3.0 * g.resolution_m;

  const int bx0 = std::max(0, static_cast<int>((eye.x() - range - idx.origin.x()) / kBinM));
  const int bx1 = std::min(idx.nx - 1, static_cast<int>((eye.x() + range - idx.origin.x()) / kBinM));
  const int by0 = std::max(0, static_cast<int>((eye.y() - range - idx.origin.y()) / kBinM));
  const int by1 = std::min(idx.ny - 1, static_cast<int>((eye.y() + range - idx.origin.y()) / kBinM));
  for (int by = by0; by <= by1; ++by) {
    for (int bx = bx0; bx <= bx1; ++bx) {
      const std::size_t b = static_cast<std::size_t>(by) * static_cast<std::size_t>(idx.nx) +
                            static_cast<std::size_t>(bx);
      for (std::uint32_t k = idx.start[b]; k < idx.start[b + 1]; ++k) {
        const std::uint32_t id = idx.ids[k];
        const Landmark& lm = landmarks_[id];
        const Eigen::Vector3d pc = t_cam_map * lm.p;
        if (pc.norm() > range) continue;
        Eigen::Vector2d uv;
        if (!Project(camera.intrinsics, pc, &uv)) continue;
        const Eigen::Vector2d d = lm.p.head<2>() - eye;
        const double dist = d.norm();
        double rel = std::atan2(d.y(), d.x()) - yaw;
        rel = std::remainder(rel, 2.0 * std::numbers::pi);
        const int ray = static_cast<int>(std::floor((rel + half_fov) / (2.0 * half_fov) * kRays));
        if (ray >= 0 && ray < kRays) {
          double wall = table[ray];
          if (ray > 0) wall = std::max(wall, table[ray - 1]);
          if (ray + 1 < kRays) wall = std::max(wall, table[ray + 1]);
          if (dist > wall + margin) continue;
        }
        if (!LineOfSight(g, eye, lm.p.head<2>())) continue;
        out->push_back({id, uv, pc.z()});
      }
    }
  }
  std::sort(out->begin(), out->end(),
            [](const VisibleLandmark& a, const VisibleLandmark& b) { return a.landmark < b.landmark; });
}

namespace {
std::atomic<std::uint64_t> g_oracle_feature_sets{0};
}  // namespace

std::uint64_t OracleFeatureSets() { return g_oracle_feature_sets.load(std::memory_order_relaxed); }

void MakeFeatures(const LandmarkMap& map, const std::vector<VisibleLandmark>& visible,
                  const Pose3& t_map_body, const CameraModel& camera, const NoiseOptions& noise,
                  bool with_points, Rng& rng, FeatureSet* out) {
  g_oracle_feature_sets.fetch_add(1, std::memory_order_relaxed);
  out->Clear();
  const auto& lms = map.landmarks();
  const std::size_t cap_in = static_cast<std::size_t>(
      std::floor(noise.max_features / (1.0 + std::max(0.0, noise.outlier_ratio))));
  // Random subset of the visible landmarks (partial Fisher-Yates over their positions).
  std::vector<std::uint32_t> order(visible.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
  const std::size_t n_in = std::min(cap_in, order.size());
  for (std::size_t i = 0; i < n_in; ++i) {
    const std::size_t j = i + rng.Below(order.size() - i);
    std::swap(order[i], order[j]);
  }
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n_in));
  const CameraIntrinsics& k = camera.intrinsics;
  const float max_u = static_cast<float>(k.width) - 1e-3f, max_v = static_cast<float>(k.height) - 1e-3f;
  const auto add = [&](const Descriptor256& d, double u, double v, const Eigen::Vector3d& p, std::int32_t lm) {
    out->descriptors.push_back(d);
    out->keypoints.push_back(std::clamp(static_cast<float>(u), 0.0f, max_u));
    out->keypoints.push_back(std::clamp(static_cast<float>(v), 0.0f, max_v));
    if (with_points) {
      out->points.push_back(static_cast<float>(p.x()));
      out->points.push_back(static_cast<float>(p.y()));
      out->points.push_back(static_cast<float>(p.z()));
    }
    out->landmark.push_back(lm);
  };
  for (std::size_t i = 0; i < n_in; ++i) {
    const VisibleLandmark& vis = visible[order[i]];
    const Landmark& lm = lms[vis.landmark];
    Descriptor256 d = lm.descriptor;
    FlipBits(rng, noise.bit_flip_probability, &d);
    const double u = vis.uv.x() + rng.Normal(0.0, noise.pixel_sigma);
    const double v = vis.uv.y() + rng.Normal(0.0, noise.pixel_sigma);
    Eigen::Vector3d p = lm.p;
    if (with_points) {
      const double s = noise.point_sigma_per_m * vis.depth_m;
      p += Eigen::Vector3d(rng.Normal(0.0, s), rng.Normal(0.0, s), rng.Normal(0.0, s));
    }
    add(d, u, v, p, static_cast<std::int32_t>(vis.landmark));
  }
  const auto n_out = static_cast<std::size_t>(std::lround(noise.outlier_ratio * static_cast<double>(n_in)));
  const Pose3 t_map_cam = CameraPoseInMap(t_map_body);
  for (std::size_t i = 0; i < n_out && !lms.empty(); ++i) {
    Descriptor256 d;
    if (rng.Bernoulli(0.5)) {
      d = lms[rng.Below(lms.size())].descriptor;  // a repeated texture: matches the wrong place
      FlipBits(rng, noise.bit_flip_probability, &d);
    } else {
      RandomDescriptor(rng, &d);
    }
    const double u = rng.Uniform(0.0, k.width), v = rng.Uniform(0.0, k.height);
    const double z = rng.Uniform(0.5, camera.range_m);
    const Eigen::Vector3d pc((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
    add(d, u, v, t_map_cam * pc, -1);
  }
}

}  // namespace zm::sim
