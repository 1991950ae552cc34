#version 450
// Terrain shading (FC5 section 7): near, the splat materials (bilinear blend of the 4 surrounding
// ids with a noise-perturbed height blend, per-material procedural detail); far, the baked albedo
// and normal; sun + sky ambient, height fog (terrain.vert), a smooth near/far transition. Debug views replace it.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(set = 0, binding = 10) uniform sampler2DArray normals_tex;
layout(set = 0, binding = 11) uniform sampler2DArray albedo_tex;
layout(set = 0, binding = 12) uniform usampler2DArray splat_tex;
layout(set = 0, binding = 13) uniform sampler2DArray cones_tex;
layout(set = 0, binding = 19) uniform sampler2DArray lit_tex;  // far colour lit per texel (src/far_light.h)

layout(location = 0) in float v_dist;
layout(location = 1) in vec2 v_node;
layout(location = 2) in float v_hole;
layout(location = 3) flat in uvec4 v_patch;
layout(location = 4) in float v_fog;  // fog amount (terrain.vert: exponential height fog)
layout(location = 0) out vec4 out_color;

// Pipelines are specialised per shading group and debug view (a CPU rasteriser executes every
// branch of a shader for every pixel: compile-time branches keep far pixels cheap).
layout(constant_id = 0) const bool kWirePass = false;
layout(constant_id = 1) const int kDebugView = TV_DEBUG_NONE;
layout(constant_id = 2) const bool kNearGroup = false;
// Holes by discard (defined behaviour). Off when holes are dropped by a NaN clip position: a shader
// without discard lets the depth test run before shading.
layout(constant_id = 3) const bool kHoleDiscard = true;
// Profiling only (FrameSettings::DrawProfile::kFlat): a constant colour, to time the rest of the draw.
layout(constant_id = 4) const bool kFlatProfile = false;
// Far group only: the colour lit per texel at upload (src/far_light.h, RendererConfig::prelit_far),
// one bilinear sample instead of the normal and albedo samples and the per-pixel lighting.
layout(constant_id = 5) const bool kPrelitFar = false;

// The colour target is UNORM holding sRGB-encoded values, and the albedo atlas is read as UNORM:
// both conversions are done here with cheap fits (within 1/255 over [0, 1]), which a CPU
// rasteriser runs far faster than sRGB attachments, sRGB texture decoding or pow().
vec3 linear_to_srgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  vec3 s1 = sqrt(c), s2 = sqrt(s1), s3 = sqrt(s2);
  return clamp(0.585122381 * s1 + 0.783140355 * s2 - 0.368262736 * s3, 0.0, 1.0);
}
vec3 srgb_to_linear(vec3 c) { return c * (c * (c * 0.305306011 + 0.682171111) + 0.012522878); }

uint hash_u(uint x) {
  x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
  return x;
}
float hash2(ivec2 p, uint seed) { return float(hash_u(uint(p.x) * 73856093u ^ uint(p.y) * 19349663u ^ seed) >> 8) * (1.0 / 16777216.0); }
vec3 hash_color(uint x) { uint h = hash_u(x); return vec3(h & 255u, (h >> 8) & 255u, (h >> 16) & 255u) / 255.0 * 0.7 + 0.3; }

// Value noise on a period-4096 wrapped coordinate (stable under camera motion).
float value_noise(vec2 p, uint seed) {
  vec2 i = floor(p), f = fract(p);
  vec2 u = f * f * (3.0 - 2.0 * f);
  ivec2 c = ivec2(i);
  float a = hash2(c, seed), b = hash2(c + ivec2(1, 0), seed);
  float cc = hash2(c + ivec2(0, 1), seed), d = hash2(c + ivec2(1, 1), seed);
  return mix(mix(a, b, u.x), mix(cc, d, u.x), u.y);
}

// Geometric levels 0..5 (roots: violet), 6.. (coarsened roots and overview levels, 32 m, 64 m, ...
// vertex spacing): light violet, lavender, then teal, cyan, grey-blue and darker greys upward.
vec3 level_color(uint level) {
  const vec3 c[12] = vec3[](vec3(0.9, 0.2, 0.2), vec3(0.95, 0.6, 0.1), vec3(0.9, 0.9, 0.2), vec3(0.2, 0.8, 0.3),
                            vec3(0.2, 0.5, 0.95), vec3(0.6, 0.3, 0.9), vec3(0.75, 0.55, 0.95), vec3(0.9, 0.8, 1.0),
                            vec3(0.2, 0.65, 0.6), vec3(0.45, 0.85, 0.9), vec3(0.55, 0.6, 0.75), vec3(0.4, 0.4, 0.45));
  return c[min(level, 11u)];
}

// Normals atlas (terrain/surface_contract.h): x in A, y in G as (v8 - 128) / 127, z rebuilt;
// ambient occlusion of the 4x4 block in R.
vec3 baked_normal(vec4 t) {
  vec2 xy = (vec2(t.a, t.g) * 255.0 - float(TV_NORMAL_CENTRE)) * (1.0 / float(TV_NORMAL_SCALE));
  float r2 = dot(xy, xy);
  if (r2 > 1.0) return vec3(xy * inversesqrt(r2), 0.0);
  return normalize(vec3(xy, sqrt(1.0 - r2)));
}

void main() {
  if (kWirePass || kFlatProfile) {
    out_color = vec4(0.02, 0.02, 0.02, 1.0);
    return;
  }
  if (kHoleDiscard && v_hole > 0.0) discard;  // defined hole method: any triangle touching a hole vertex
  uint slot = v_patch.x & 0xFFFFu;
  if (kPrelitFar) {
    // Hole texels are transparent black, as in the albedo: undo their bleed into the bilinear colour.
    vec4 a = texture(lit_tex, vec3((v_node + float(TV_APRON)) / float(TV_TEXELS), float(slot)));
    vec3 color = float(TV_LIT_SCALE) * srgb_to_linear(a.a > 0.01 ? a.rgb / a.a : a.rgb);
    out_color = vec4(linear_to_srgb(mix(color, frame.fog.rgb, clamp(v_fog, 0.0, 1.0))), 1.0);
    return;
  }
  uint level = (v_patch.x >> TV_PATCH_LEVEL_SHIFT) & TV_PATCH_LEVEL_MASK;  // geometric level
  vec3 uvw = vec3((v_node + float(TV_APRON)) / float(TV_TEXELS), float(slot));
  vec4 normal_texel = texture(normals_tex, uvw);
  vec3 n = baked_normal(normal_texel);
  float ao = normal_texel.r;
  float dist = v_dist;
  vec3 sun = frame.sun_dir.xyz;  // unit length (set_frame)
  const int debug_view = kDebugView;

  vec3 albedo;
  if (debug_view == TV_DEBUG_NONE || debug_view == TV_DEBUG_WIRE) {
    // Hole texels decode as transparent black: undo their bleed into the bilinear colour.
    vec4 a = texture(albedo_tex, uvw);
    vec3 far_albedo = srgb_to_linear(a.a > 0.01 ? a.rgb / a.a : a.rgb);
    albedo = far_albedo;
    float near_w = 1.0 - smoothstep(frame.lod.z, frame.lod.w, dist);
    if (kNearGroup && near_w > 0.0) {
      // World xy modulo 4096 m for the noise (stable under camera motion). Node origins are
      // multiples of their size, which divides 4096 m: wrap the origin, then add the offset.
      uint node_level = level - (v_patch.x >> TV_PATCH_COARSE_SHIFT);
      vec2 v_wrap = mod(vec2(v_patch.zw) * float(64u << node_level), 4096.0) + v_node * (0.5 * float(1u << node_level));
      // Splat sample (a, b) sits on node vertex (2a, 2b): bilinear over the 4 surrounding ids.
      vec2 sc = v_node * 0.5;
      ivec2 b = clamp(ivec2(floor(sc)), ivec2(0), ivec2(TV_SPLAT_SAMPLES - 2));
      vec2 f = clamp(sc - vec2(b), 0.0, 1.0);
      float w[4] = float[](((1.0 - f.x) * (1.0 - f.y)), (f.x * (1.0 - f.y)), ((1.0 - f.x) * f.y), (f.x * f.y));
      uint ids[4];
      for (int k = 0; k < 4; ++k) ids[k] = texelFetch(splat_tex, ivec3(b + ivec2(k & 1, k >> 1), int(slot)), 0).r;
      // One weight per distinct id (its bilinear coverage): per-sample weights would make the
      // perturbation's reach depend on the position within the texel, a pattern on the texel grid.
      for (int k = 1; k < 4; ++k)
        for (int j = 0; j < k; ++j)
          if (w[k] > -1.0 && ids[j] == ids[k]) { w[j] += w[k]; w[k] = -2.0; }
      // Noise-perturbed transition (seed 003), sized to the splat texel of this level (65 samples
      // over 64 m * 2^L: 2^L m): each material's own height pattern moves the 50 % line by up to
      // height_blend texels, with features of 0.8 texel, so the line wanders off the grid at
      // every level without sub-pixel shimmer when far. 1.25 / texel keeps the 4096 m wrap whole.
      float texel_m = float(1u << node_level);
      vec2 tp = v_wrap * (1.25 / texel_m);
      float score[4];
      float best = -1e9;
      for (int k = 0; k < 4; ++k) {
        float h = value_noise(tp, ids[k] * 7919u + 1u);
        score[k] = w[k] < -1.0 ? -1e9 : w[k] + 2.0 * palette.materials[ids[k]].detail.z * (h - 0.5);
        best = max(best, score[k]);
      }
      float total = 0.0;
      vec3 mixed = vec3(0.0), base = vec3(0.0);
      for (int k = 0; k < 4; ++k) {
        if (w[k] < -1.0) continue;
        Material m = palette.materials[ids[k]];
        base += m.albedo_roughness.rgb * w[k];
        float wk = max(score[k] - best + 0.2, 0.0);
        float scale = max(m.detail.x, 0.05);
        float detail = value_noise(v_wrap / scale, ids[k] * 31u + 5u) * 0.65 +
                       value_noise(v_wrap * (4.0 / scale), ids[k] * 31u + 9u) * 0.35;
        vec3 c = m.albedo_roughness.rgb * (1.0 + m.detail.y * (detail - 0.5) * 2.0);
        mixed += c * wk;
        total += wk;
      }
      vec3 near_albedo = mixed / max(total, 1e-6);
      // The baked albedo is the bilinear palette blend times the cook's large-scale variation, one
      // factor for all channels (format/SPEC.md 16.3): carry that factor (far / base, in
      // luminance: the hue stays the palette's, free of BC1 chroma error) into the near colour, so
      // both agree in mean colour and the near/far switch does not show. (An orthophoto is no
      // palette colour: detail.w = 0 leaves the near colour as it was.)
      const vec3 lum = vec3(0.2126, 0.7152, 0.0722);
      float variation = dot(far_albedo, lum) / max(dot(base, lum), 1e-4);
      near_albedo *= mix(1.0, variation, palette.materials[ids[0]].detail.w);
      albedo = mix(far_albedo, near_albedo, near_w);
    }
  } else if (debug_view == TV_DEBUG_LOD) {
    albedo = level_color(level);
  } else if (debug_view == TV_DEBUG_NODES) {
    albedo = hash_color(v_patch.z * 9781u ^ v_patch.w * 6271u ^ level * 131u);
  } else if (debug_view == TV_DEBUG_PATCHES) {
    albedo = hash_color(v_patch.x * 2654435761u ^ v_patch.y * 97u);
    if (v_patch.y != 0u) albedo = mix(albedo, vec3(1.0, 0.0, 0.0), 0.5);  // stitched patches reddish
  } else if (debug_view == TV_DEBUG_CONES) {
    uint px = (v_patch.x >> TV_PATCH_PX_SHIFT) & 7u, py = (v_patch.x >> TV_PATCH_PY_SHIFT) & 7u;
    vec4 c = texelFetch(cones_tex, ivec3(int(px), int(py), int(slot)), 0);
    float angle = c.a * 90.0;  // degrees (terrain/surface_contract.h); alpha 255 = never cull
    albedo = c.a > 0.998 ? vec3(0.8, 0.1, 0.1) : mix(vec3(0.1, 0.8, 0.2), vec3(0.9, 0.9, 0.1), angle / 90.0);
  } else if (debug_view == TV_DEBUG_HOLES) {
    albedo = v_hole < 0.0 ? vec3(1.0, 0.0, 0.0) : vec3(0.6);
  } else if (debug_view == TV_DEBUG_NORMALS) {
    out_color = vec4(n * 0.5 + 0.5, 1.0);  // raw, not a colour: no sRGB encode
    return;
  } else {  // TV_DEBUG_SPLAT: nearest splat id, palette colour
    ivec2 s = clamp(ivec2(round(v_node * 0.5)), ivec2(0), ivec2(TV_SPLAT_SAMPLES - 1));
    uint id = texelFetch(splat_tex, ivec3(s, int(slot)), 0).r;
    albedo = palette.materials[id].albedo_roughness.rgb;
  }

  float ndl = max(dot(n, sun), 0.0);
  vec3 color;
  if (debug_view == TV_DEBUG_NONE || debug_view == TV_DEBUG_WIRE) {
    vec3 ambient = frame.sky_color.rgb * (0.55 + 0.45 * n.z) * frame.sun_color.w * (0.4 + 0.6 * ao);
    color = albedo * (frame.sun_color.rgb * ndl + ambient);
    color = mix(color, frame.fog.rgb, clamp(v_fog, 0.0, 1.0));
  } else {
    color = albedo * (0.35 + 0.65 * ndl);  // debug colours, lit just enough to read the shape
  }
  out_color = vec4(linear_to_srgb(color), 1.0);
}
