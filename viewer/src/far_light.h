// The scene's light (sun and sky) and the far field lit per texel at upload: on a CPU rasteriser
// (lavapipe) the far shader's two bilinear samples and its per-pixel lighting are most of the
// shading cost, so the light is applied once per texel when a node arrives and the far shader
// samples one texture (viewer/README.md, pipeline step 6). The near (splat) group, the debug views
// and any frame whose sun differs from the baked one keep per-pixel lighting.
#pragma once
#include <cstdint>
#include <vector>

namespace terrain::view {

inline constexpr double kDefaultSunAzimuthDeg = 125, kDefaultSunElevationDeg = 24;

struct SceneLight {
  float sun_dir[3] = {};    // unit, towards the sun
  float sun_color[4] = {};  // linear rgb, w ambient strength
  float sky_color[3] = {};  // linear rgb
};
SceneLight scene_light(double sun_azimuth_deg, double sun_elevation_deg);

// The light's two terms per normal texel (its A and G bytes): max(n . sun, 0) and the sky's
// (0.55 + 0.45 n.z) * ambient strength. Built once per light (512 KB), so a node's texels need no
// square root.
struct TexelLighting {
  SceneLight light;
  std::vector<float> sun, sky;  // index A << 8 | G
};
TexelLighting texel_lighting(const SceneLight& light);

// Lights `count` texels of a node: `normals` and `albedo` are the decoded RGBA8 atlases (normal x in
// A, y in G, ambient occlusion in R; albedo sRGB with the hole alpha), as terrain.frag reads them.
// Writes RGBA8: the sRGB code (under the shader's decoding fit) nearest to albedo * light / TV_LIT_SCALE,
// alpha 255; hole texels (alpha 0) stay transparent black, as the albedo's do.
void light_texels(const uint8_t* normals, const uint8_t* albedo, int count, const TexelLighting& lighting, uint8_t* out);

// The shader's sRGB decoding fit (terrain.frag srgb_to_linear), for one 8-bit code.
float srgb_code_to_linear_fit(uint8_t code);

}  // namespace terrain::view
