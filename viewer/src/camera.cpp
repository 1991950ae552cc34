#include "camera.h"

#include <algorithm>
#include <cmath>

namespace terrain::view {

void camera_forward(const Camera& c, double f[3]) {
  f[0] = std::sin(c.yaw) * std::cos(c.pitch);
  f[1] = std::cos(c.yaw) * std::cos(c.pitch);
  f[2] = std::sin(c.pitch);
}

void look_at(Camera& c, const double t[3]) {
  const double dx = t[0] - c.position[0], dy = t[1] - c.position[1], dz = t[2] - c.position[2];
  const double horizontal = std::hypot(dx, dy);
  c.yaw = horizontal > 0 ? std::atan2(dx, dy) : c.yaw;
  c.pitch = std::atan2(dz, horizontal);
}

double pixels_per_radian(double fovy, uint32_t height) { return double(height) / (2.0 * std::tan(fovy * 0.5)); }

void camera_basis(const Camera& c, double r[3], double up[3], double f[3]) {
  camera_forward(c, f);
  r[0] = f[1];
  r[1] = -f[0];
  r[2] = 0;
  double rl = std::hypot(r[0], r[1]);
  if (rl < 1e-12) {
    r[0] = std::cos(c.yaw);
    r[1] = -std::sin(c.yaw);
    rl = 1;
  }
  r[0] /= rl;
  r[1] /= rl;
  up[0] = r[1] * f[2] - r[2] * f[1];
  up[1] = r[2] * f[0] - r[0] * f[2];
  up[2] = r[0] * f[1] - r[1] * f[0];
}

void unproject(const Camera& c, uint32_t width, uint32_t height, double px, double py, float depth, double out[3]) {
  double r[3], up[3], f[3];
  camera_basis(c, r, up, f);
  const double t = std::tan(c.fovy * 0.5), aspect = double(width) / double(height);
  const double ndc_x = (px + 0.5) / width * 2 - 1, ndc_y = (py + 0.5) / height * 2 - 1;
  const double w = c.near_m / double(depth);  // forward distance
  const double a = ndc_x * w * aspect * t, b = -ndc_y * w * t;
  for (int k = 0; k < 3; ++k) out[k] = r[k] * a + up[k] * b + f[k] * w;
}

void fill_view_uniforms(const Camera& c, const WorldInfo& world, uint32_t width, uint32_t height, FrameUniforms& u) {
  // Camera position relative to the world origin, split into whole half metres and a remainder.
  const double local_x = c.position[0] - world.origin_x_m;
  const double local_y = c.position[1] - world.origin_y_m;
  const double hx = std::floor(local_x * 2.0), hy = std::floor(local_y * 2.0);
  u.cam_hm[0] = int32_t(hx);
  u.cam_hm[1] = int32_t(hy);
  u.cam_frac[0] = float(local_x - hx * 0.5);
  u.cam_frac[1] = float(local_y - hy * 0.5);
  u.cam_frac[2] = float(c.position[2]);
  u.cam_frac[3] = float(pixels_per_radian(c.fovy, height));
  // Detail noise repeats every 4096 m; 4096 is a multiple of every node size, so a node never
  // straddles a wrap and the shader can add the node's wrapped origin.
  u.wrap_origin[0] = float(std::fmod(local_x, 4096.0));
  u.wrap_origin[1] = float(std::fmod(local_y, 4096.0));

  // View basis (frame axes: x east, y north, z up); view space looks down -z.
  double f[3];
  camera_forward(c, f);
  double r[3] = {f[1], -f[0], 0.0};  // forward x up
  double rl = std::hypot(r[0], r[1]);
  if (rl < 1e-12) {  // looking straight up or down: use the heading for "right"
    r[0] = std::cos(c.yaw);
    r[1] = -std::sin(c.yaw);
    rl = 1;
  }
  r[0] /= rl;
  r[1] /= rl;
  const double up[3] = {r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
  const double t = std::tan(c.fovy * 0.5);
  const double aspect = double(width) / double(height);
  const double sx = 1.0 / (aspect * t), sy = 1.0 / t;
  // clip.x = sx * dot(r, p); clip.y = -sy * dot(up, p) (Vulkan y down); clip.z = near; clip.w = dot(f, p).
  double m[16] = {};
  for (int i = 0; i < 3; ++i) {
    m[i * 4 + 0] = sx * r[i];
    m[i * 4 + 1] = -sy * up[i];
    m[i * 4 + 2] = 0;
    m[i * 4 + 3] = f[i];
  }
  m[12] = 0;
  m[13] = 0;
  m[14] = c.near_m;
  m[15] = 0;
  for (int i = 0; i < 16; ++i) u.view_proj[i] = float(m[i]);
  // Gribb-Hartmann planes from the float matrix (rows of M): left, right, bottom, top, near, far.
  auto row = [&](int rr, int k) { return double(u.view_proj[k * 4 + rr]); };
  const int sign_row[6][2] = {{0, 1}, {0, -1}, {1, 1}, {1, -1}, {2, -1}, {2, 0}};
  for (int p = 0; p < 6; ++p) {
    for (int k = 0; k < 4; ++k) {
      const double base = p == 5 ? 0.0 : row(3, k);
      const double other = p == 5 ? row(2, k) : sign_row[p][1] * row(sign_row[p][0], k);
      u.planes[p][k] = float(base + other);
    }
  }
  u.viewport[0] = float(width);
  u.viewport[1] = float(height);
  u.viewport[2] = 1.0f / float(width);
  u.viewport[3] = 1.0f / float(height);
}

bool project(const FrameUniforms& u, const float p[3], double& px, double& py, double& depth) {
  double clip[4];
  for (int rr = 0; rr < 4; ++rr)
    clip[rr] = u.view_proj[0 * 4 + rr] * double(p[0]) + u.view_proj[1 * 4 + rr] * double(p[1]) +
               u.view_proj[2 * 4 + rr] * double(p[2]) + u.view_proj[3 * 4 + rr];
  if (clip[3] <= 0) return false;
  px = (clip[0] / clip[3] * 0.5 + 0.5) * u.viewport[0];
  py = (clip[1] / clip[3] * 0.5 + 0.5) * u.viewport[1];
  depth = clip[2] / clip[3];
  return true;
}

}  // namespace terrain::view

namespace terrain::view {

void lod_window(const WorldInfo& world, double cam_x, double cam_y, uint32_t out[4]) {
  auto axis = [](uint32_t roots, double local_m, uint32_t& origin, uint32_t& size) {
    const uint32_t w = std::min<uint32_t>(roots, TV_LODMAP_WINDOW_ROOTS);
    const double r = std::floor(local_m / node_size_m(kRootLevel)) - double(w / 2);
    const uint32_t o = uint32_t(std::clamp(r, 0.0, double(roots - w)));
    origin = o << kRootLevel;
    size = w << kRootLevel;
  };
  axis(world.roots_x, cam_x - world.origin_x_m, out[0], out[2]);
  axis(world.roots_y, cam_y - world.origin_y_m, out[1], out[3]);
}

int64_t lod_index(const FrameUniforms& u, int64_t sx, int64_t sy) {
  if (sx < 0 || sy < 0 || sx >= int64_t(u.world[2]) || sy >= int64_t(u.world[3])) return -1;
  const int64_t lx = sx - int64_t(u.lodwin[0]), ly = sy - int64_t(u.lodwin[1]);
  if (lx >= 0 && ly >= 0 && lx < int64_t(u.lodwin[2]) && ly < int64_t(u.lodwin[3])) return ly * u.lodwin[2] + lx;
  return int64_t(u.lodwin[2]) * u.lodwin[3] + (sy >> kRootLevel) * int64_t(u.world[0]) + (sx >> kRootLevel);
}

}  // namespace terrain::view
