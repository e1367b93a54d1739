// P3P by Grunert's quartic (see p3p.h for the method and its invariants).
#include "localization/p3p.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace zm {
namespace {

// Value and derivative of an ascending polynomial by Horner's rule.
void Eval(const double* c, int degree, double x, double* f, double* df) {
  double p = c[degree];
  double d = 0.0;
  for (int i = degree - 1; i >= 0; --i) {
    d = d * x + p;
    p = p * x + c[i];
  }
  *f = p;
  *df = d;
}

// The single root of a polynomial that is monotonic on [a, b] and changes sign there (f(a) has
// the sign of fa). Newton steps that leave the bracket fall back to bisection, so it converges.
double RootInBracket(const double* c, int degree, double a, double b, double fa) {
  double x = 0.5 * (a + b);
  for (int it = 0; it < 100; ++it) {
    double f = 0.0;
    double df = 0.0;
    Eval(c, degree, x, &f, &df);
    if (f == 0.0) return x;
    if ((f < 0.0) == (fa < 0.0)) {
      a = x;
    } else {
      b = x;
    }
    double next = df != 0.0 ? x - f / df : 0.5 * (a + b);
    if (!(next > a && next < b)) next = 0.5 * (a + b);
    if (std::abs(next - x) <= 1e-15 * std::max(1.0, std::abs(x)) || b - a <= 0.0) return next;
    x = next;
  }
  return x;
}

// Product of two ascending polynomials: out has degree da + db (<= 4 here).
void Multiply(const double* a, int da, const double* b, int db, double* out) {
  for (int i = 0; i <= da + db; ++i) out[i] = 0.0;
  for (int i = 0; i <= da; ++i) {
    for (int j = 0; j <= db; ++j) out[i + j] += a[i] * b[j];
  }
}

double Horner(const double* c, int degree, double x) {
  double p = c[degree];
  for (int i = degree - 1; i >= 0; --i) p = p * x + c[i];
  return p;
}

// Orthonormal frame of a triangle: first edge, normal, and their cross product (columns).
Eigen::Matrix3d TriangleFrame(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                              const Eigen::Vector3d& p3) {
  const Eigen::Vector3d e1 = (p2 - p1).normalized();
  const Eigen::Vector3d e2 = (p2 - p1).cross(p3 - p1).normalized();
  Eigen::Matrix3d b;
  b.col(0) = e1;
  b.col(1) = e2;
  b.col(2) = e1.cross(e2);
  return b;
}

}  // namespace

int RealPolynomialRoots(const double* c, int degree, double lo, double hi, double* roots) {
  double max_abs = 0.0;
  for (int i = 0; i <= degree; ++i) max_abs = std::max(max_abs, std::abs(c[i]));
  if (max_abs == 0.0 || !(lo < hi)) return 0;
  // A vanishing leading coefficient lowers the degree (its root would lie beyond any bound).
  while (degree > 0 && std::abs(c[degree]) <= 1e-14 * max_abs) --degree;
  if (degree == 0) return 0;
  if (degree == 1) {
    const double x = -c[0] / c[1];
    if (x > lo && x <= hi) {
      roots[0] = x;
      return 1;
    }
    return 0;
  }
  // Between consecutive real roots of the derivative the polynomial is monotonic: each such
  // interval holds at most one root, found by a bracketed search when the sign changes.
  double derivative[4] = {};  // zeroed: GCC -O3 cannot see through the recursion that it is set
  for (int i = 0; i < degree; ++i) derivative[i] = (i + 1) * c[i + 1];
  double breaks[6];
  breaks[0] = lo;
  const int critical = RealPolynomialRoots(derivative, degree - 1, lo, hi, breaks + 1);
  int nb = critical + 1;
  if (breaks[nb - 1] < hi) breaks[nb++] = hi;
  int count = 0;
  double fa = Horner(c, degree, breaks[0]);
  for (int k = 0; k + 1 < nb; ++k) {
    const double a = breaks[k];
    const double b = breaks[k + 1];
    const double fb = Horner(c, degree, b);
    if (fb == 0.0) {
      roots[count++] = b;
    } else if (fa != 0.0 && (fa < 0.0) != (fb < 0.0)) {
      roots[count++] = RootInBracket(c, degree, a, b, fa);
    }
    fa = fb;
    if (count == 4) break;
  }
  return count;
}

int SolveP3p(const std::array<Eigen::Vector3d, 3>& world,
             const std::array<Eigen::Vector3d, 3>& bearing, std::array<P3pPose, 4>* out) {
  std::array<Eigen::Vector3d, 3> j;
  for (std::size_t k = 0; k < 3; ++k) {
    const double norm = bearing[k].norm();
    if (!(norm > 0.0) || !std::isfinite(norm)) return 0;
    j[k] = bearing[k] / norm;
  }
  const Eigen::Vector3d& x1 = world[0];
  const Eigen::Vector3d& x2 = world[1];
  const Eigen::Vector3d& x3 = world[2];
  // Squared side lengths opposite the bearing angles alpha (2-3), beta (1-3), gamma (1-2).
  const double a2 = (x2 - x3).squaredNorm();
  const double b2 = (x1 - x3).squaredNorm();
  const double c2 = (x1 - x2).squaredNorm();
  if (!(a2 > 1e-18 && b2 > 1e-18 && c2 > 1e-18)) return 0;
  // Collinear world points: sin of the angle at x1 below 1e-6 leaves the pose undetermined.
  if ((x2 - x1).cross(x3 - x1).squaredNorm() <= 1e-12 * b2 * c2) return 0;
  const double ca = j[1].dot(j[2]);
  const double cb = j[0].dot(j[2]);
  const double cg = j[0].dot(j[1]);
  if (ca > 1.0 - 1e-12 || cb > 1.0 - 1e-12 || cg > 1.0 - 1e-12) return 0;  // coincident rays

  // Work with side lengths scaled by 1/b2 so the quartic's coefficients are O(1).
  const double a = a2 / b2;
  const double c = c2 / b2;
  const double k1 = a - c;
  // Q(v) = s1^-2 b2 = 1 + v^2 - 2 v cb;  u(v) = N(v) / D(v)  (the conics' difference, linear in u);
  // quartic: D^2 + N^2 - 2 cg N D - c Q D^2 = 0  (the (1,2) conic times D^2).
  const double q[3] = {1.0, -2.0 * cb, 1.0};
  const double n[3] = {k1 + 1.0, -2.0 * cb * k1, k1 - 1.0};
  const double d[2] = {2.0 * cg, -2.0 * ca};
  double d2[3], n2[5], nd[4], qd2[5];
  Multiply(d, 1, d, 1, d2);
  Multiply(n, 2, n, 2, n2);
  Multiply(n, 2, d, 1, nd);
  Multiply(q, 2, d2, 2, qd2);
  double poly[5];
  for (int i = 0; i <= 4; ++i) {
    poly[i] = n2[i] - c * qd2[i];
    if (i <= 2) poly[i] += d2[i];
    if (i <= 3) poly[i] -= 2.0 * cg * nd[i];
  }
  // Cauchy's bound on the roots' magnitude, from the highest non-negligible coefficient.
  int degree = 4;
  double max_abs = 0.0;
  for (double p : poly) max_abs = std::max(max_abs, std::abs(p));
  if (!(max_abs > 0.0) || !std::isfinite(max_abs)) return 0;
  while (degree > 0 && std::abs(poly[degree]) <= 1e-14 * max_abs) --degree;
  if (degree == 0) return 0;
  double bound = 0.0;
  for (int i = 0; i < degree; ++i) bound = std::max(bound, std::abs(poly[i] / poly[degree]));
  double roots[4];
  const int nr = RealPolynomialRoots(poly, degree, 0.0, 1.0 + bound, roots);

  const Eigen::Matrix3d world_frame = TriangleFrame(x1, x2, x3);
  const Eigen::Vector3d world_centroid = (x1 + x2 + x3) / 3.0;
  int count = 0;
  for (int r = 0; r < nr; ++r) {
    const double v = roots[r];
    const double dv = d[0] + d[1] * v;
    if (std::abs(dv) < 1e-12) continue;
    const double u = Horner(n, 2, v) / dv;
    const double qv = Horner(q, 2, v);
    if (!(u > 0.0) || !(qv > 0.0)) continue;
    Eigen::Vector3d s;
    s[0] = std::sqrt(b2 / qv);
    s[1] = u * s[0];
    s[2] = v * s[0];
    // Two Newton steps on the three law-of-cosines equations remove the quartic's rounding.
    for (int it = 0; it < 2; ++it) {
      const Eigen::Vector3d f(s[1] * s[1] + s[2] * s[2] - 2.0 * ca * s[1] * s[2] - a2,
                              s[0] * s[0] + s[2] * s[2] - 2.0 * cb * s[0] * s[2] - b2,
                              s[0] * s[0] + s[1] * s[1] - 2.0 * cg * s[0] * s[1] - c2);
      Eigen::Matrix3d jac;
      jac << 0.0, 2.0 * s[1] - 2.0 * ca * s[2], 2.0 * s[2] - 2.0 * ca * s[1],  //
          2.0 * s[0] - 2.0 * cb * s[2], 0.0, 2.0 * s[2] - 2.0 * cb * s[0],     //
          2.0 * s[0] - 2.0 * cg * s[1], 2.0 * s[1] - 2.0 * cg * s[0], 0.0;
      const double det = jac.determinant();
      if (!(std::abs(det) > 1e-300)) break;
      const Eigen::Vector3d step = jac.inverse() * f;
      const Eigen::Vector3d next = s - step;
      const Eigen::Vector3d fn(
          next[1] * next[1] + next[2] * next[2] - 2.0 * ca * next[1] * next[2] - a2,
          next[0] * next[0] + next[2] * next[2] - 2.0 * cb * next[0] * next[2] - b2,
          next[0] * next[0] + next[1] * next[1] - 2.0 * cg * next[0] * next[1] - c2);
      if (!(fn.squaredNorm() < f.squaredNorm()) || !(next.minCoeff() > 0.0)) break;
      s = next;
    }
    const Eigen::Vector3d p1 = s[0] * j[0];
    const Eigen::Vector3d p2 = s[1] * j[1];
    const Eigen::Vector3d p3 = s[2] * j[2];
    P3pPose& pose = (*out)[static_cast<std::size_t>(count)];
    pose.r_cam_world = TriangleFrame(p1, p2, p3) * world_frame.transpose();
    pose.t_cam_world = (p1 + p2 + p3) / 3.0 - pose.r_cam_world * world_centroid;
    if (!pose.r_cam_world.allFinite() || !pose.t_cam_world.allFinite()) continue;
    ++count;
  }
  return count;
}

}  // namespace zm
