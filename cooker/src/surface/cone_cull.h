// Patch cone: texel layout and the exact runtime back-face test the viewer must use.
// Header-only, no dependencies: the viewer (GLSL port), the cooker and the tests share it.
//
// Cone texture: BC3 8x8 per node, texel (p, q) = patch p east, q north (rows south to north).
// Read with texelFetch (no filtering) as UNORM; v8 = round(channel * 255):
//   R: axis x (east)   x = (v8 - 132) / 123   (132 is a 5-bit endpoint value: x = 0 is exact)
//   G: axis y (north)  y = (v8 - 130) / 125   (130 is a 6-bit endpoint value: y = 0 is exact)
//   B: 0 (unused)
//   A: half-angle      theta = v8 / 255 * 90 degrees;  v8 = 255 means "never cull"
//   axis z = sqrt(max(0, 1 - x^2 - y^2)), then the axis is normalised.
// Every triangle normal the renderer draws in the patch (including stitched edge triangles,
// edge collapse d <= 4) lies within theta of the decoded axis, with margins for GPU decoder
// differences (see format/SPEC.md section 16), so the test below is conservative as written.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace terrain::cone {

inline constexpr double kHalfPi = 1.57079632679489661923;

struct DecodedCone {
  double axis[3] = {0, 0, 1};
  double half_angle_rad = kHalfPi;
  bool never_cull = true;
};

inline constexpr double kConeRCentre = 132, kConeRScale = 123, kConeGCentre = 130, kConeGScale = 125;
inline double cone_axis_x(double r8) { return (r8 - kConeRCentre) / kConeRScale; }
inline double cone_axis_y(double g8) { return (g8 - kConeGCentre) / kConeGScale; }

inline DecodedCone decode_cone_texel(uint8_t r, uint8_t g, uint8_t a) {
  DecodedCone c;
  double x = cone_axis_x(r), y = cone_axis_y(g);
  const double rr = x * x + y * y;
  double z = rr < 1.0 ? std::sqrt(1.0 - rr) : 0.0;
  const double len = std::sqrt(x * x + y * y + z * z);
  c.axis[0] = x / len;
  c.axis[1] = y / len;
  c.axis[2] = z / len;
  c.half_angle_rad = double(a) / 255.0 * kHalfPi;
  c.never_cull = a == 255;
  return c;
}

// True when no triangle of the patch can face the eye: for every corner C of the patch box
// (the patch's x/y footprint times [min height, max height]; node min/max are fine),
//   dot(C - eye, axis) >= sin(theta) * |C - eye|.
// The left side minus the right is concave in C, so checking the 8 box corners covers every
// point of the box, and for every normal n within theta of the axis, dot(P - eye, n) >= 0.
inline bool cone_patch_backfacing(const DecodedCone& c, const double eye[3], const double box_min[3],
                                  const double box_max[3]) {
  if (c.never_cull || c.half_angle_rad >= kHalfPi) return false;
  const double s = std::sin(c.half_angle_rad);
  for (int k = 0; k < 8; ++k) {
    const double p[3] = {(k & 1) ? box_max[0] : box_min[0], (k & 2) ? box_max[1] : box_min[1],
                         (k & 4) ? box_max[2] : box_min[2]};
    const double d[3] = {p[0] - eye[0], p[1] - eye[1], p[2] - eye[2]};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (d[0] * c.axis[0] + d[1] * c.axis[1] + d[2] * c.axis[2] < s * len) return false;
  }
  return true;
}

}  // namespace terrain::cone
