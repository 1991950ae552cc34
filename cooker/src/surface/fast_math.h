// Small deterministic approximations for hot loops (pure IEEE arithmetic: same bits on every
// thread). Error bounds are stated; callers that need exact angles use <cmath>.
#pragma once
#include <cmath>

namespace terrain::cook {

// The minimax polynomial of atan on [0, 1] (|error| < 1.1e-5 rad): one definition for the forms below.
inline double atan_poly(double t) {
  const double t2 = t * t;
  return t * (0.99997726 + t2 * (-0.33262347 + t2 * (0.19354346 + t2 * (-0.11643287 + t2 * (0.05265332 + t2 * -0.01172120)))));
}

// atan(x) for x >= 0, |error| < 1.1e-5 rad (the polynomial on [0, 1], reflected above 1).
inline double fast_atan(double x) {
  const bool inv = x > 1.0;
  const double p = atan_poly(inv ? 1.0 / x : x);
  return inv ? 1.5707963267948966 - p : p;
}

// fast_atan() as selects (no branch, so a loop of it vectorises): the same operations on the path
// fast_atan() takes, hence the same doubles (1 / x is computed either way, and dropped for x <= 1).
inline double fast_atan_select(double x) {
  const bool inv = x > 1.0;
  const double r = 1.0 / x;
  const double p = atan_poly(inv ? r : x);
  return inv ? 1.5707963267948966 - p : p;
}

// atan2(y, x) for y >= 0 (an angle in [0, pi]), same error bound.
inline double fast_atan2_pos(double y, double x) {
  if (x == 0) return y == 0 ? 0.0 : 1.5707963267948966;
  const double a = fast_atan(y / std::fabs(x));
  return x > 0 ? a : 3.141592653589793 - a;
}

// fast_atan2_pos() as selects (no branches, so a loop of it vectorises): the same operations on
// every path that fast_atan2_pos() takes, hence the same doubles.
inline double fast_atan2_pos_select(double y, double x) {
  const double a = fast_atan_select(y / std::fabs(x));  // x == 0: inf or NaN, replaced below
  const double r = x > 0 ? a : 3.141592653589793 - a;
  return x == 0 ? (y == 0 ? 0.0 : 1.5707963267948966) : r;
}

// Angle between unit vectors a and b (radians), error < 2e-5 rad, accurate for tiny angles.
inline double fast_angle(const double a[3], const double b[3]) {
  const double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2], cz = a[0] * b[1] - a[1] * b[0];
  return fast_atan2_pos(std::sqrt(cx * cx + cy * cy + cz * cz), a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
}

}  // namespace terrain::cook
