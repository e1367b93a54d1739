// Planar polygon geometry for zones: containment, distance to the boundary, area, simplicity
// checks and half-plane clipping. Polygons are outer rings in map-frame metres, stored without
// the repeated closing vertex, either orientation. Every function here is allocation-free except
// ClipToHalfPlane (which builds its result) and reads its input only.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace zm {

struct Box2 {
  Eigen::Vector2d min{0.0, 0.0};
  Eigen::Vector2d max{0.0, 0.0};
  [[nodiscard]] bool Contains(const Eigen::Vector2d& p) const {
    return p.x() >= min.x() && p.x() <= max.x() && p.y() >= min.y() && p.y() <= max.y();
  }
  [[nodiscard]] bool Overlaps(const Box2& o, double margin = 0.0) const {
    return min.x() <= o.max.x() + margin && o.min.x() <= max.x() + margin &&
           min.y() <= o.max.y() + margin && o.min.y() <= max.y() + margin;
  }
};

// Axis-aligned bounds of a non-empty ring.
[[nodiscard]] Box2 BoundingBox(std::span<const Eigen::Vector2d> ring);

// Even-odd rule; points exactly on an edge may go either way (callers use distances for that).
[[nodiscard]] bool PointInPolygon(std::span<const Eigen::Vector2d> ring, const Eigen::Vector2d& p);

// Euclidean distance from p to the nearest edge of the ring (>= 0, inside or outside).
[[nodiscard]] double DistanceToBoundary(std::span<const Eigen::Vector2d> ring,
                                        const Eigen::Vector2d& p);

// Distance between two closed segments (0 when they touch or cross).
[[nodiscard]] double SegmentDistance(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1,
                                     const Eigen::Vector2d& b0, const Eigen::Vector2d& b1);

// Smallest distance between the boundaries of two rings (0 when they touch or cross).
[[nodiscard]] double RingDistance(std::span<const Eigen::Vector2d> a,
                                  std::span<const Eigen::Vector2d> b);

// Signed shoelace area: positive for counter-clockwise rings.
[[nodiscard]] double SignedArea(std::span<const Eigen::Vector2d> ring);

// If two non-adjacent edges of the ring touch or cross (or two adjacent edges fold back onto
// each other), returns the indices of the first such pair of edges (edge i joins vertex i and
// i+1). O(n^2), fine for room outlines.
[[nodiscard]] std::optional<std::pair<std::size_t, std::size_t>> FindSelfIntersection(
    std::span<const Eigen::Vector2d> ring);

// Keeps the part of the ring where dot(p, normal) <= offset (Sutherland–Hodgman against one
// half-plane). Convex input gives convex output; a concave ring cut into several pieces comes
// back as one ring joined by zero-width bridges along the cut line, which containment handles.
// Returns an empty ring if nothing is kept.
[[nodiscard]] std::vector<Eigen::Vector2d> ClipToHalfPlane(std::span<const Eigen::Vector2d> ring,
                                                           const Eigen::Vector2d& normal,
                                                           double offset);

}  // namespace zm
