// Planar polygon geometry for zones (see polygon.h). Plain loops over the ring, no allocation
// except in ClipToHalfPlane.
#include "zones/polygon.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace zm {
namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

double PointSegmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  double t = len2 > 0.0 ? (p - a).dot(ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// Orientation sign with a tolerance scaled to the segment lengths, so nearly collinear
// configurations count as touching rather than flipping on rounding.
int Orientation(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const double v = Cross(b - a, c - a);
  const double scale = (b - a).norm() * (c - a).norm();
  const double eps = 1e-12 * std::max(scale, 1e-300);
  if (v > eps) return 1;
  if (v < -eps) return -1;
  return 0;
}

bool OnSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  return p.x() >= std::min(a.x(), b.x()) - 1e-12 && p.x() <= std::max(a.x(), b.x()) + 1e-12 &&
         p.y() >= std::min(a.y(), b.y()) - 1e-12 && p.y() <= std::max(a.y(), b.y()) + 1e-12;
}

bool SegmentsTouch(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1,
                   const Eigen::Vector2d& b0, const Eigen::Vector2d& b1) {
  const int o1 = Orientation(a0, a1, b0);
  const int o2 = Orientation(a0, a1, b1);
  const int o3 = Orientation(b0, b1, a0);
  const int o4 = Orientation(b0, b1, a1);
  if (o1 != o2 && o3 != o4 && o1 != 0 && o2 != 0 && o3 != 0 && o4 != 0) return true;
  if (o1 == 0 && OnSegment(a0, a1, b0)) return true;
  if (o2 == 0 && OnSegment(a0, a1, b1)) return true;
  if (o3 == 0 && OnSegment(b0, b1, a0)) return true;
  return o4 == 0 && OnSegment(b0, b1, a1);
}

}  // namespace

Box2 BoundingBox(std::span<const Eigen::Vector2d> ring) {
  Box2 box;
  if (ring.empty()) return box;
  box.min = box.max = ring[0];
  for (const auto& v : ring) {
    box.min = box.min.cwiseMin(v);
    box.max = box.max.cwiseMax(v);
  }
  return box;
}

bool PointInPolygon(std::span<const Eigen::Vector2d> ring, const Eigen::Vector2d& p) {
  bool inside = false;
  const std::size_t n = ring.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[j];
    if ((a.y() > p.y()) != (b.y() > p.y())) {
      const double x = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (p.x() < x) inside = !inside;
    }
  }
  return inside;
}

double DistanceToBoundary(std::span<const Eigen::Vector2d> ring, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  const std::size_t n = ring.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    best = std::min(best, PointSegmentDistance(p, ring[j], ring[i]));
  }
  return best;
}

double SegmentDistance(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1,
                       const Eigen::Vector2d& b0, const Eigen::Vector2d& b1) {
  if (SegmentsTouch(a0, a1, b0, b1)) return 0.0;
  return std::min({PointSegmentDistance(a0, b0, b1), PointSegmentDistance(a1, b0, b1),
                   PointSegmentDistance(b0, a0, a1), PointSegmentDistance(b1, a0, a1)});
}

double RingDistance(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0, pi = a.size() - 1; i < a.size(); pi = i++) {
    for (std::size_t j = 0, pj = b.size() - 1; j < b.size(); pj = j++) {
      best = std::min(best, SegmentDistance(a[pi], a[i], b[pj], b[j]));
      if (best == 0.0) return 0.0;
    }
  }
  return best;
}

double SignedArea(std::span<const Eigen::Vector2d> ring) {
  double twice = 0.0;
  const std::size_t n = ring.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) twice += Cross(ring[j], ring[i]);
  return 0.5 * twice;
}

std::optional<std::pair<std::size_t, std::size_t>> FindSelfIntersection(
    std::span<const Eigen::Vector2d> ring) {
  const std::size_t n = ring.size();
  if (n < 3) return std::nullopt;
  auto edge = [&](std::size_t i) { return std::pair{ring[i], ring[(i + 1) % n]}; };
  for (std::size_t i = 0; i < n; ++i) {
    const auto [a0, a1] = edge(i);
    // Adjacent edge folding back (a spike): the next edge turns by 180 degrees.
    const auto [n0, n1] = edge((i + 1) % n);
    if (Orientation(a0, a1, n1) == 0 && (a1 - a0).dot(n1 - n0) < 0.0) {
      return std::pair{i, (i + 1) % n};
    }
    for (std::size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // adjacent through the closing vertex
      const auto [b0, b1] = edge(j);
      if (SegmentsTouch(a0, a1, b0, b1)) return std::pair{i, j};
    }
  }
  return std::nullopt;
}

std::vector<Eigen::Vector2d> ClipToHalfPlane(std::span<const Eigen::Vector2d> ring,
                                             const Eigen::Vector2d& normal, double offset) {
  std::vector<Eigen::Vector2d> out;
  const std::size_t n = ring.size();
  out.reserve(n + 2);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& cur = ring[i];
    const Eigen::Vector2d& nxt = ring[(i + 1) % n];
    const double dc = normal.dot(cur) - offset;
    const double dn = normal.dot(nxt) - offset;
    if (dc <= 0.0) out.push_back(cur);
    if ((dc < 0.0 && dn > 0.0) || (dc > 0.0 && dn < 0.0)) {
      const double t = dc / (dc - dn);
      out.push_back(cur + t * (nxt - cur));
    }
  }
  // Drop consecutive duplicates produced by vertices lying on the cut line.
  std::vector<Eigen::Vector2d> ring_out;
  ring_out.reserve(out.size());
  for (const auto& v : out) {
    if (ring_out.empty() || (ring_out.back() - v).norm() > 1e-12) ring_out.push_back(v);
  }
  while (ring_out.size() > 1 && (ring_out.front() - ring_out.back()).norm() <= 1e-12) {
    ring_out.pop_back();
  }
  if (ring_out.size() < 3 || std::abs(SignedArea(ring_out)) <= 1e-12) ring_out.clear();
  return ring_out;
}

}  // namespace zm
