// Bindings and helpers shared by every terrain shader. Layouts mirror src/gpu_types.h.
#include "config.h"

layout(std140, set = 0, binding = 0) uniform Frame {
  mat4 view_proj;
  vec4 planes[6];
  ivec4 cam_hm;
  vec4 cam_frac;    // x, y remainder (m); z camera height (m); w pixels per radian
  vec4 lod;         // x error target px; y cone margin; z, w near-shading start, end (m)
  uvec4 world;      // roots_x, roots_y, sectors_x, sectors_y
  uvec4 misc;       // top level (5, or 5 + K overview levels), flags, debug view, patch capacity
  vec4 sun_dir;
  vec4 sun_color;   // w: ambient strength
  vec4 sky_color;
  vec4 fog;         // rgb, density per metre
  vec4 viewport;
  vec4 wrap_origin;
  uvec4 lodwin;     // LOD map window around the camera: x0, y0, width, height in sectors (config.h)
} frame;

// The streamer's SlotDescriptor (terrain/streamer.h), uploaded as it is.
struct NodeDesc {
  int min_height, max_height, height_offset;
  float geometric_error;
  uint x, y, packed;  // level | step_log2 << 8 | flags << 16 | child_mask << 24
  uint reserved;
};
layout(std430, set = 0, binding = 1) readonly buffer NodeDescs { NodeDesc nodes[]; };
layout(std430, set = 0, binding = 2) readonly buffer PatchBounds { ivec2 patch_bounds[]; };
layout(set = 0, binding = 3) uniform usampler2D root_tex;  // R16_UINT, a texel per root (config.h "Tree buffer")
// Per slot: total error (m) of the node drawn with coarsening c in component c (roots only).
layout(std430, set = 0, binding = 15) readonly buffer CoarseErrors { vec4 coarse_error[]; };

struct Material {
  vec4 albedo_roughness;
  vec4 detail;      // scale m, strength, height blend, 1 = albedo baked from the palette
};
layout(std140, set = 0, binding = 14) uniform Palette {
  Material materials[TV_MAX_MATERIALS];
  vec4 cone_sin2[64];  // 256 floats: sin^2(half angle + margin) per cone alpha, < 0 = never cull
} palette;

uint node_level(NodeDesc d) { return d.packed & 0xFFu; }
uint node_step(NodeDesc d) { return (d.packed >> 8) & 0xFFu; }
uint level_width(uint level) { return frame.world.x << (TV_ROOT_LEVEL - level); }

// Camera-relative coordinates of exact half-metre integers and height units (see camera.h).
float rel_x(int half_metres) { precise float r = float(half_metres - frame.cam_hm.x) * 0.5 - frame.cam_frac.x; return r; }
float rel_y(int half_metres) { precise float r = float(half_metres - frame.cam_hm.y) * 0.5 - frame.cam_frac.y; return r; }
float rel_z(int units) { precise float r = float(units) * (1.0 / 1024.0) - frame.cam_frac.z; return r; }
int half_metres(uint node_coord, uint level, uint node_index) {
  return int((node_coord * uint(TV_QUADS_PER_NODE) + node_index) << level);
}

// Index into the LOD map buffer (config.h "LOD map") of sector (sx, sy); -1 outside the world.
int lod_index(int sx, int sy) {
  if (sx < 0 || sy < 0 || sx >= int(frame.world.z) || sy >= int(frame.world.w)) return -1;
  int lx = sx - int(frame.lodwin.x), ly = sy - int(frame.lodwin.y);
  if (lx >= 0 && ly >= 0 && lx < int(frame.lodwin.z) && ly < int(frame.lodwin.w)) return ly * int(frame.lodwin.z) + lx;
  return int(frame.lodwin.z * frame.lodwin.w) + (sy >> TV_ROOT_LEVEL) * int(frame.world.x) + (sx >> TV_ROOT_LEVEL);
}
// Whether root (x, y) lies inside the LOD map window (only those may split, config.h).
bool root_in_window(uint x, uint y) {
  uint wx = frame.lodwin.x >> TV_ROOT_LEVEL, wy = frame.lodwin.y >> TV_ROOT_LEVEL;
  return x >= wx && y >= wy && x < wx + (frame.lodwin.z >> TV_ROOT_LEVEL) && y < wy + (frame.lodwin.w >> TV_ROOT_LEVEL);
}
