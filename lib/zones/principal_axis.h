// Principal-axis cuts of point sets: the one derivation of "split these keyframes along their
// main direction" for oversize zones (split.h) and for the offline segmentation's keyframe caps
// and keyframe-only zones (segment/split.h).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <span>

namespace zm {

// The unit eigenvectors of the points' covariance: column 1 the principal (largest-variance)
// axis, column 0 the other. An eigenvector's sign is Eigen's (arbitrary); callers that name
// parts by their order fix it.
[[nodiscard]] Eigen::Matrix2d PrincipalAxes(std::span<const Eigen::Vector2d> points);

// The cut along `axis` nearest the median that has points on both sides: midway between the
// two distinct consecutive projections nearest the middle. Points whose projection is <= the
// returned value lie on one side, the rest on the other. nullopt when every point projects to
// one value (or there are fewer than two).
[[nodiscard]] std::optional<double> MedianCut(std::span<const Eigen::Vector2d> points,
                                              const Eigen::Vector2d& axis);

}  // namespace zm
