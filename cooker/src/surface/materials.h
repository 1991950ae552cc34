// Material palette and procedural splat rules (Frostbite-style masks from height, slope,
// curvature, aspect and world-space noise). The JSON format is documented in format/SPEC.md section 16.4.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "surface_layers.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// A soft range mask: 1 inside [lo, hi], 0 outside [lo - fade/2, hi + fade/2], linear in between
// (0.5 exactly at lo and hi). fade = 0 gives a hard step. For aspect the range may wrap (lo > hi).
struct MaskRange {
  bool active = false;
  double lo = 0, hi = 0, fade = 0;
  double inv_fade = 0;  // 1 / fade (0 when fade is 0), set by the parser
};

struct NoiseTerm {
  double amplitude = 0;   // added to the mask before the 0.5 threshold; 0 = no noise
  double scale_m = 32;    // wavelength of the first octave, metres
  int octaves = 3;
  uint32_t seed = 0;
};

struct MaterialRule {
  uint8_t material = 0;   // palette index
  MaskRange height_m;     // metres above the datum
  MaskRange slope_deg;    // 0 = flat, 90 = vertical
  MaskRange curvature;    // Laplacian of height, 1/m: > 0 concave (hollows), < 0 convex (ridges)
  MaskRange aspect_deg;   // compass direction the slope faces: 0 north, 90 east; ignored below 1 degree of slope
  NoiseTerm noise;
  // Scale (metres) over which height, slope, curvature and aspect are Gaussian-filtered before the
  // masks read them (sigma of the filter); 0 = per sample. See splat.cpp and SPEC section 16.4.
  double scale_m = 0;
  uint8_t scale_index = 0;  // index into MaterialRules::scales (set by the parser)
};

// Terrain attributes at one splat sample (see splat.cpp for how they are measured).
struct SurfaceSample {
  double x_m = 0, y_m = 0;   // frame coordinates
  double height_m = 0;
  double slope_deg = 0;
  double curvature = 0;
  double aspect_deg = 0;
  double min_noise_wavelength_m = 0;  // noise octaves shorter than this are left out (0 = all)
};

// Each distinct rule scale costs one filtered height field per node.
inline constexpr size_t kMaxRuleScales = 4;

struct MaterialRules {
  std::vector<Material> palette;      // at most 256
  std::vector<MaterialRule> rules;    // priority order: the first rule whose score >= 0.5 wins
  uint8_t default_material = 0;       // when no rule matches, and for samples without data
  // Document-level "scale_m": the default of rules without one, and the scale of the class
  // raster's mode filter (--landcover). 0 = per sample (the behaviour of files without the key).
  double scale_m = 0;
  // Distinct rule scales (metres), in first-use order; rules index it with scale_index.
  std::vector<double> scales;
  // Document-level "despeckle": a sample whose id differs from all 4 lattice neighbours takes
  // their most common id (thin lines, 2 samples wide or 1 sample wide and connected, survive).
  bool despeckle = false;
  // Document-level "band_limit_noise": rule noise octaves shorter than 2 splat spacings (4 vertex
  // spacings) are left out at that level, so the noise cannot alias into per-sample speckle.
  bool band_limit_noise = false;
  std::string source;                 // file path, or "built-in"
};

// The built-in palette and rules (also written out by `default_rules_json()`).
MaterialRules default_material_rules();
// The built-in rules as a JSON document in the documented file format (a starting point for users).
std::string default_rules_json();
// Parses a rules document; `origin` names it in error messages.
Status parse_material_rules(const std::string& json_text, const std::string& origin, MaterialRules& out);

// Value of one mask at v (0..1).
double mask_value(const MaskRange& m, double v);
double aspect_mask_value(const MaskRange& m, double aspect_deg);
// Palette index chosen for one sample. Deterministic; pure function of the sample and the rules.
uint8_t choose_material(const MaterialRules& rules, const SurfaceSample& s);
// Same with one sample per entry of rules.scales (rule r reads per_scale[r.scale_index]).
uint8_t choose_material_scaled(const MaterialRules& rules, const SurfaceSample* per_scale);

// The attributes of a row of samples at one rule scale, an array per attribute (samples at the
// same y; attributes no rule reads may be left null).
struct SampleRow {
  const double* height_m = nullptr;
  const double* slope_deg = nullptr;
  const double* curvature = nullptr;
  const double* aspect_deg = nullptr;
};
// choose_material_scaled for n <= kMaxRowSamples samples of a row at once (sample k: attributes
// per_scale[s].*[k], noise at (x_m[k], y_m) with min_noise_wavelength_m): the same choices, with
// each rule's mask computed for the whole row in vector loops and noise only where a mask lies in
// its rule's noise band before the first rule that claims the sample outright (rule by rule, a row
// at a time: fbm_noise_row). `wanted`
// (may be null: all) marks the samples whose choice is used; the others' out[k] is unspecified, and
// once every wanted sample is claimed outright the later rules are not evaluated.
inline constexpr int kMaxRowSamples = 128;
void choose_materials_row(const MaterialRules& rules, const SampleRow* per_scale, const double* x_m, double y_m,
                          double min_noise_wavelength_m, int n, const uint8_t* wanted, uint8_t* out);

}  // namespace terrain::cook
