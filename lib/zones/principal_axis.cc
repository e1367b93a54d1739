// Principal-axis cuts (principal_axis.h).
#include "zones/principal_axis.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <vector>

namespace zm {

Eigen::Matrix2d PrincipalAxes(std::span<const Eigen::Vector2d> points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& p : points) cov += (p - mean) * (p - mean).transpose();
  // Eigenvalues ascending: the largest one's vector is the last column.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  return eig.eigenvectors();
}

std::optional<double> MedianCut(std::span<const Eigen::Vector2d> points,
                                const Eigen::Vector2d& axis) {
  std::vector<double> sorted;
  sorted.reserve(points.size());
  for (const Eigen::Vector2d& p : points) sorted.push_back(p.dot(axis));
  std::sort(sorted.begin(), sorted.end());
  const std::size_t n = sorted.size();
  for (std::size_t off = 0; off < n; ++off) {
    for (std::size_t k : {n / 2 + off, n / 2 - std::min(off, n / 2)}) {
      if (k >= 1 && k < n && sorted[k - 1] < sorted[k]) return 0.5 * (sorted[k - 1] + sorted[k]);
    }
  }
  return std::nullopt;
}

}  // namespace zm
