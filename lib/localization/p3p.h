// P3P minimal solver: the camera poses that map three world points onto three bearing rays.
//
// Method: Grunert's (1841) formulation as reviewed by Haralick et al. (IJCV 1994). With unit
// bearings j1, j2, j3 and unknown depths s1, s2, s3, the law of cosines on the three point pairs
// gives three quadrics; substituting s2 = u s1, s3 = v s1 and eliminating s1 leaves two
// conics in (u, v), whose difference is linear in u. Back-substituting u(v) gives a quartic in v,
// built here by fixed-size polynomial products (no hand-expanded coefficients to get wrong).
// Only positive roots with positive u are kept (points in front of the camera). The rotation is
// taken between orthonormal frames spanned by the triangle in the world and in the camera, so it
// is always a proper rotation even when a root is slightly off.
//
// No allocation: everything is on the stack. Real roots come from derivative bracketing with a
// safeguarded Newton step (RealPolynomialRoots), which cannot miss a simple root in the interval.
#pragma once

#include <Eigen/Core>
#include <array>

namespace zm {

struct P3pPose {
  Eigen::Matrix3d r_cam_world;  // x_cam = r_cam_world * x_world + t_cam_world
  Eigen::Vector3d t_cam_world;
};

// At most four solutions. Returns how many were written to `out`; 0 for a degenerate triangle
// (collinear or coincident world points, coincident bearings) or when no root is valid.
// Bearings need not be unit length; they must point along the rays (z > 0 for a pinhole).
int SolveP3p(const std::array<Eigen::Vector3d, 3>& world,
             const std::array<Eigen::Vector3d, 3>& bearing, std::array<P3pPose, 4>* out);

// Real roots in (lo, hi] of the polynomial c[0] + c[1] x + ... + c[degree] x^degree, degree <= 4,
// ascending, written to `roots` (capacity 4). Simple roots are found exactly (to rounding); a
// double root is found only where it coincides with a sign change of the polynomial.
int RealPolynomialRoots(const double* c, int degree, double lo, double hi, double* roots);

}  // namespace zm
