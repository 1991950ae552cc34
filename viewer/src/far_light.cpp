#include "far_light.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "../shaders/config.h"

namespace terrain::view {

SceneLight scene_light(double sun_azimuth_deg, double sun_elevation_deg) {
  SceneLight l;
  const double az = sun_azimuth_deg * M_PI / 180.0, el = sun_elevation_deg * M_PI / 180.0;
  l.sun_dir[0] = float(std::sin(az) * std::cos(el));
  l.sun_dir[1] = float(std::cos(az) * std::cos(el));
  l.sun_dir[2] = float(std::sin(el));
  l.sun_color[0] = 2.9f;
  l.sun_color[1] = 2.75f;
  l.sun_color[2] = 2.45f;
  l.sun_color[3] = 0.42f;  // ambient strength
  l.sky_color[0] = 0.42f;
  l.sky_color[1] = 0.55f;
  l.sky_color[2] = 0.78f;
  return l;
}

float srgb_code_to_linear_fit(uint8_t code) {
  const float c = code / 255.0f;
  return c * (c * (c * 0.305306011f + 0.682171111f) + 0.012522878f);
}

namespace {

// Linear values half way between consecutive codes' decoded values: the code nearest to x under
// the shader's fit is the number of midpoints below x. A table over [0, 1] gives a code at most a
// few off, which the midpoints then correct (a binary search per channel cost 2.8 ms per node).
struct CodeMidpoints {
  static constexpr int kBins = 4096;
  std::array<float, 256> mid;  // mid[255] = +inf
  std::array<uint8_t, kBins> start;
  CodeMidpoints() {
    for (int k = 0; k < 255; ++k) mid[size_t(k)] = 0.5f * (srgb_code_to_linear_fit(uint8_t(k)) + srgb_code_to_linear_fit(uint8_t(k + 1)));
    mid[255] = std::numeric_limits<float>::infinity();
    for (int i = 0; i < kBins; ++i)
      start[size_t(i)] = uint8_t(std::upper_bound(mid.begin(), mid.begin() + 255, float(i) / kBins) - mid.begin());
  }
  uint8_t nearest(float x) const {
    if (!(x > 0.0f)) return 0;
    int code = start[size_t(std::min(int(x * kBins), kBins - 1))];
    while (x >= mid[size_t(code)]) ++code;  // mid[255] is +inf: stops at 255
    return uint8_t(code);
  }
};

}  // namespace

TexelLighting texel_lighting(const SceneLight& light) {
  TexelLighting t;
  t.light = light;
  t.sun.resize(size_t(1) << 16);
  t.sky.resize(size_t(1) << 16);
  for (int a = 0; a < 256; ++a)
    for (int g = 0; g < 256; ++g) {
      // terrain.frag baked_normal(): x in A, y in G, z rebuilt.
      const float x = (float(a) - float(TV_NORMAL_CENTRE)) * (1.0f / float(TV_NORMAL_SCALE));
      const float y = (float(g) - float(TV_NORMAL_CENTRE)) * (1.0f / float(TV_NORMAL_SCALE));
      const float r2 = x * x + y * y;
      float n[3];
      if (r2 > 1.0f) {
        const float s = 1.0f / std::sqrt(r2);
        n[0] = x * s, n[1] = y * s, n[2] = 0.0f;
      } else {
        const float z = std::sqrt(1.0f - r2), s = 1.0f / std::sqrt(r2 + z * z);
        n[0] = x * s, n[1] = y * s, n[2] = z * s;
      }
      const size_t k = size_t(a) << 8 | size_t(g);
      t.sun[k] = std::max(n[0] * light.sun_dir[0] + n[1] * light.sun_dir[1] + n[2] * light.sun_dir[2], 0.0f);
      t.sky[k] = (0.55f + 0.45f * n[2]) * light.sun_color[3];
    }
  return t;
}

void light_texels(const uint8_t* normals, const uint8_t* albedo, int count, const TexelLighting& lighting, uint8_t* out) {
  static const CodeMidpoints codes;
  static const auto linear = [] {
    std::array<float, 256> t;
    for (int k = 0; k < 256; ++k) t[size_t(k)] = srgb_code_to_linear_fit(uint8_t(k));
    return t;
  }();
  const SceneLight& light = lighting.light;
  const float inv_scale = float(1.0 / TV_LIT_SCALE);
  for (int i = 0; i < count; ++i) {
    const uint8_t* nt = normals + 4 * i;
    const uint8_t* at = albedo + 4 * i;
    uint8_t* o = out + 4 * i;
    if (at[3] == 0) {  // hole: transparent black, as the albedo's own texel
      o[0] = o[1] = o[2] = o[3] = 0;
      continue;
    }
    const size_t k = size_t(nt[3]) << 8 | size_t(nt[1]);
    const float ndl = lighting.sun[k];
    const float ambient = lighting.sky[k] * (0.4f + 0.6f * (nt[0] / 255.0f));
    for (int c = 0; c < 3; ++c) {
      const float lit = linear[at[c]] * (light.sun_color[c] * ndl + light.sky_color[c] * ambient);
      o[c] = codes.nearest(lit * inv_scale);
    }
    o[3] = 255;
  }
}

}  // namespace terrain::view
