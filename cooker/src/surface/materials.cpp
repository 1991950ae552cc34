// Material palette, rules file parsing and the per-sample rule evaluation.
#include "materials.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "avx2_clones.h"
#include "noise.h"

namespace terrain::cook {
namespace {

using json = nlohmann::json;
constexpr double kInf = std::numeric_limits<double>::infinity();

// The built-in rules file. Kept as JSON so the default goes through the same parser as user files
// and users can start from it (default_rules_json()).
constexpr const char* kDefaultRulesJson = R"JSON({
  "format": "terrain-material-rules",
  "version": 1,
  "materials": [
    {"name": "grass",         "albedo_srgb": [ 92, 110,  58], "roughness": 0.90, "detail_scale_m": 2.0, "detail_strength": 0.25, "height_blend": 0.30},
    {"name": "forest_floor",  "albedo_srgb": [ 60,  72,  42], "roughness": 0.95, "detail_scale_m": 3.0, "detail_strength": 0.30, "height_blend": 0.40},
    {"name": "alpine_meadow", "albedo_srgb": [120, 124,  82], "roughness": 0.90, "detail_scale_m": 2.0, "detail_strength": 0.25, "height_blend": 0.30},
    {"name": "bare_soil",     "albedo_srgb": [126, 104,  80], "roughness": 0.85, "detail_scale_m": 2.0, "detail_strength": 0.20, "height_blend": 0.40},
    {"name": "rock",          "albedo_srgb": [112, 106,  98], "roughness": 0.75, "detail_scale_m": 6.0, "detail_strength": 0.35, "height_blend": 0.80},
    {"name": "cliff",         "albedo_srgb": [ 84,  80,  76], "roughness": 0.70, "detail_scale_m": 12.0, "detail_strength": 0.40, "height_blend": 0.90},
    {"name": "scree",         "albedo_srgb": [142, 136, 126], "roughness": 0.80, "detail_scale_m": 3.0, "detail_strength": 0.30, "height_blend": 0.60},
    {"name": "snow",          "albedo_srgb": [232, 236, 240], "roughness": 0.35, "detail_scale_m": 8.0, "detail_strength": 0.10, "height_blend": 0.20},
    {"name": "sand",          "albedo_srgb": [196, 182, 140], "roughness": 0.85, "detail_scale_m": 1.5, "detail_strength": 0.15, "height_blend": 0.20},
    {"name": "mud",           "albedo_srgb": [ 88,  72,  56], "roughness": 0.40, "detail_scale_m": 1.5, "detail_strength": 0.20, "height_blend": 0.10},
    {"name": "water",         "albedo_srgb": [ 46,  64,  74], "roughness": 0.05, "detail_scale_m": 8.0, "detail_strength": 0.05, "height_blend": 0.00}
  ],
  "default_material": "grass",
  "scale_m": 16,
  "despeckle": true,
  "band_limit_noise": true,
  "rules": [
    {"material": "water",  "height_m": {"max": 0.3, "fade": 0.4}, "slope_deg": {"max": 3, "fade": 2}},
    {"material": "cliff",  "scale_m": 1, "slope_deg": {"min": 52, "fade": 6}, "noise": {"amplitude": 0.2, "scale_m": 16, "octaves": 2, "seed": 1}},
    {"material": "snow",   "height_m": {"min": 2900, "fade": 250}, "slope_deg": {"max": 42, "fade": 8},
                           "noise": {"amplitude": 0.35, "scale_m": 80, "octaves": 3, "seed": 2}},
    {"material": "rock",   "slope_deg": {"min": 38, "fade": 8}, "noise": {"amplitude": 0.3, "scale_m": 24, "octaves": 3, "seed": 3}},
    {"material": "scree",  "slope_deg": {"min": 26, "max": 42, "fade": 6}, "curvature": {"min": 0.0, "fade": 0.004},
                           "noise": {"amplitude": 0.25, "scale_m": 20, "octaves": 2, "seed": 4}},
    {"material": "sand",   "height_m": {"max": 3, "fade": 2}, "slope_deg": {"max": 10, "fade": 4}},
    {"material": "alpine_meadow", "height_m": {"min": 2000, "fade": 200}, "noise": {"amplitude": 0.3, "scale_m": 60, "octaves": 3, "seed": 5}},
    {"material": "mud",    "curvature": {"min": 0.02, "fade": 0.02}, "slope_deg": {"max": 5, "fade": 3},
                           "noise": {"amplitude": 0.3, "scale_m": 12, "octaves": 2, "seed": 6}},
    {"material": "bare_soil", "aspect_deg": {"min": 135, "max": 225, "fade": 40}, "slope_deg": {"min": 15, "max": 36, "fade": 6},
                           "noise": {"amplitude": 0.3, "scale_m": 30, "octaves": 3, "seed": 7}},
    {"material": "forest_floor", "height_m": {"min": 20, "max": 1800, "fade": 100}, "slope_deg": {"min": 4, "max": 34, "fade": 6},
                           "noise": {"amplitude": 0.45, "scale_m": 90, "octaves": 3, "seed": 8}}
  ]
})JSON";

Status bad(const std::string& origin, const std::string& what) {
  return Status::failure(Error::invalid_argument, "material rules " + origin + ": " + what);
}

Status check_keys(const json& obj, std::initializer_list<const char*> allowed, const std::string& origin,
                  const std::string& where) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool ok = false;
    for (const char* a : allowed) ok = ok || it.key() == a;
    if (!ok) {
      std::string list;
      for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
      return bad(origin, where + ": unknown key \"" + it.key() + "\" (valid: " + list + ")");
    }
  }
  return Status::success();
}

Status read_number(const json& obj, const char* key, double lo, double hi, double& out, const std::string& origin,
                   const std::string& where) {
  if (!obj.contains(key)) return Status::success();
  const json& v = obj[key];
  if (!v.is_number()) return bad(origin, where + ": \"" + key + "\" must be a number");
  const double d = v.get<double>();
  if (!std::isfinite(d) || d < lo || d > hi) {
    std::ostringstream msg;
    msg << where << ": \"" << key << "\" = " << d << " is outside [" << lo << ", " << hi << "]";
    return bad(origin, msg.str());
  }
  out = d;
  return Status::success();
}

Status read_range(const json& rule, const char* key, double lo_limit, double hi_limit, MaskRange& out,
                  const std::string& origin, const std::string& where) {
  if (!rule.contains(key)) return Status::success();
  const json& r = rule[key];
  const std::string w = where + "." + key;
  if (!r.is_object()) return bad(origin, w + " must be an object like {\"min\": a, \"max\": b, \"fade\": f}");
  if (Status s = check_keys(r, {"min", "max", "fade"}, origin, w); !s.ok()) return s;
  if (!r.contains("min") && !r.contains("max")) return bad(origin, w + " needs \"min\" or \"max\"");
  out.active = true;
  out.lo = -kInf;
  out.hi = kInf;
  out.fade = 0;
  if (Status s = read_number(r, "min", lo_limit, hi_limit, out.lo, origin, w); !s.ok()) return s;
  if (Status s = read_number(r, "max", lo_limit, hi_limit, out.hi, origin, w); !s.ok()) return s;
  if (Status s = read_number(r, "fade", 0, 1e6, out.fade, origin, w); !s.ok()) return s;
  out.inv_fade = out.fade > 0 ? 1.0 / out.fade : 0.0;
  return Status::success();
}

}  // namespace

namespace {
// Inlined into the per-sample rule loop (the public mask_value() is the same function).
inline double mask_of(const MaskRange& m, double v) {
  if (!m.active) return 1.0;
  if (m.fade <= 0) return (v >= m.lo && v <= m.hi) ? 1.0 : 0.0;
  const double a = (v - m.lo) * m.inv_fade + 0.5;
  const double b = (m.hi - v) * m.inv_fade + 0.5;
  return std::clamp(std::min(a, b), 0.0, 1.0);
}
}  // namespace

double mask_value(const MaskRange& m, double v) { return mask_of(m, v); }

namespace {
// fmod(fmod(x, 360) + 360, 360) without the library calls for |x| < 360 (every aspect rule's
// case): there fmod(x, 360) is x, and for u = x + 360 in [360, 720) fmod(u, 360) is u - 360 exactly
// (Sterbenz), so the results are the same doubles.
inline double wrap360(double x) {
  if (!(x > -360.0 && x < 360.0)) return std::fmod(std::fmod(x, 360.0) + 360.0, 360.0);
  const double u = x + 360.0;
  return u < 360.0 ? u : u < 720.0 ? u - 360.0 : std::fmod(u, 360.0);
}
}  // namespace

double aspect_mask_value(const MaskRange& m, double aspect_deg) {
  if (!m.active) return 1.0;
  // Distance outside the (possibly wrapping) arc [lo, hi], in degrees along the circle.
  const double lo = wrap360(m.lo);
  const double width = wrap360(m.hi - m.lo);
  const double into = wrap360(aspect_deg - lo);  // 0..360 from lo
  double outside = 0;  // 0 inside the arc, else the angular distance to the nearer end
  if (into > width) outside = std::min(into - width, 360.0 - into);
  if (m.fade <= 0) return outside > 0 ? 0.0 : 1.0;
  const double inside_depth = outside > 0 ? -outside : std::min(into, width - into);
  return std::clamp(inside_depth * m.inv_fade + 0.5, 0.0, 1.0);
}

namespace {
// Score of one rule on one sample: true when it claims the sample.
bool rule_matches(const MaterialRule& r, const SurfaceSample& s) {
    double mask = mask_of(r.height_m, s.height_m);
    if (mask > 0) mask *= mask_of(r.slope_deg, s.slope_deg);
    if (mask > 0) mask *= mask_of(r.curvature, s.curvature);
    if (mask > 0 && s.slope_deg >= 1.0) mask *= aspect_mask_value(r.aspect_deg, s.aspect_deg);
    const double amp = r.noise.amplitude;
    // The noise only matters inside the transition band, so it is evaluated lazily there.
    if (mask - amp >= 0.5) return true;
    if (mask + amp < 0.5) return false;
    const double n = fbm_noise(s.x_m, s.y_m, r.noise.scale_m, r.noise.octaves, r.noise.seed, s.min_noise_wavelength_m);
    return mask + amp * n >= 0.5;
}
}  // namespace

uint8_t choose_material(const MaterialRules& rules, const SurfaceSample& s) {
  for (const MaterialRule& r : rules.rules)
    if (rule_matches(r, s)) return r.material;
  return rules.default_material;
}

uint8_t choose_material_scaled(const MaterialRules& rules, const SurfaceSample* per_scale) {
  for (const MaterialRule& r : rules.rules)
    if (rule_matches(r, per_scale[r.scale_index])) return r.material;
  return rules.default_material;
}

namespace {
// GCC's vector extensions, 4 lanes (one AVX2 register, two SSE2 ones): the auto-vectoriser keeps
// these loops' selects as branches. Lanes only widen the loops; every lane computes rule_matches'
// operations in its order, so the doubles are the per-sample ones on every CPU.
typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));
typedef uint64_t V4u __attribute__((vector_size(32)));
constexpr int kLanes = 4;
static_assert(kMaxRowSamples % kLanes == 0);

// Loads and stores as memcpy (unaligned; no function takes a V4d by value: that ABI needs AVX).
#define TERRAIN_LOAD4(T, var, p) \
  T var;                          \
  std::memcpy(&var, (p), sizeof var)
#define TERRAIN_STORE4(p, v)           \
  do {                                 \
    const auto stored_ = (v);          \
    std::memcpy((p), &stored_, sizeof stored_); \
  } while (0)

// A row's attribute padded to whole lanes (the padding's masks are never read).
int padded(int n) { return (n + kLanes - 1) / kLanes * kLanes; }

// m[k] = mask_of(r, v[k]) when `first`, else m[k] * mask_of(r, v[k]) where m[k] > 0 (rule_matches'
// product, same operations), for k < padded(n): m has room for kMaxRowSamples. An inactive range
// is 1 everywhere: it leaves m as it is. (Not a template: clang's target_clones refuses those.)
TERRAIN_AVX2_CLONES void range_mask_row(const MaskRange& r, const double* v_in, int n, bool first, double* m) {
  if (!r.active) {
    if (first) std::fill(m, m + padded(n), 1.0);
    return;
  }
  alignas(32) double v[kMaxRowSamples];
  std::copy(v_in, v_in + n, v);
  std::fill(v + n, v + padded(n), 0.0);
  const V4d lo = {r.lo, r.lo, r.lo, r.lo}, hi = {r.hi, r.hi, r.hi, r.hi};
  const V4d inv = {r.inv_fade, r.inv_fade, r.inv_fade, r.inv_fade};
  const V4d zero = {0, 0, 0, 0}, half = {0.5, 0.5, 0.5, 0.5}, one = {1, 1, 1, 1};
  const bool hard = r.fade <= 0;
  for (int k = 0; k < n; k += kLanes) {
    TERRAIN_LOAD4(V4d, x, v + k);
    V4d mask;
    if (hard) {
      mask = ((x >= lo) & (x <= hi)) ? one : zero;
    } else {
      // std::clamp(std::min(a, b), 0.0, 1.0) as libstdc++ spells it: min(max(t, 0), 1).
      const V4d a = (x - lo) * inv + half;
      const V4d b = (hi - x) * inv + half;
      const V4d t = (b < a) ? b : a;
      const V4d c = (t < zero) ? zero : t;
      mask = (one < c) ? one : c;
    }
    if (first) {
      TERRAIN_STORE4(m + k, mask);
    } else {
      TERRAIN_LOAD4(V4d, before, m + k);
      TERRAIN_STORE4(m + k, (before > zero) ? before * mask : before);
    }
  }
}

// m[k] *= aspect_mask_value(r, aspect[k]) where m[k] > 0 and slope[k] >= 1 (rule_matches). The loop
// takes wrap360's branch for |aspect - lo| < 360 (every measured aspect: 0..360); other samples
// are done again by aspect_mask_value itself.
void aspect_mask_row(const MaskRange& r, const double* aspect, const double* slope, int n, double* m) {
  if (!r.active) return;
  const double lo = wrap360(r.lo), width = wrap360(r.hi - r.lo), inv = r.inv_fade;
  const bool hard = r.fade <= 0;
  double before[kMaxRowSamples];
  std::copy(m, m + n, before);
  int slow = 0;
  for (int k = 0; k < n; ++k) {
    const double x = aspect[k] - lo;
    slow += !(x > -360.0 && x < 360.0);
    const double u = x + 360.0;
    const double into = u < 360.0 ? u : u - 360.0;
    const double outside = into > width ? std::min(into - width, 360.0 - into) : 0.0;
    const double depth = outside > 0 ? -outside : std::min(into, width - into);
    const double val = hard ? (outside > 0 ? 0.0 : 1.0) : std::clamp(depth * inv + 0.5, 0.0, 1.0);
    m[k] = m[k] > 0 && slope[k] >= 1.0 ? m[k] * val : m[k];
  }
  if (slow == 0) return;
  for (int k = 0; k < n; ++k) {
    const double x = aspect[k] - lo;
    if (!(x > -360.0 && x < 360.0))
      m[k] = before[k] > 0 && slope[k] >= 1.0 ? before[k] * aspect_mask_value(r, aspect[k]) : before[k];
  }
}

// Per sample k < padded(n): bit `bit` of claims[k] where m[k] - amp >= 0.5 (the rule claims it
// outright), of maybe[k] where it lies in the noise band (neither that nor m[k] + amp < 0.5).
// Returns how many samples with want[k] set no rule has claimed yet.
TERRAIN_AVX2_CLONES int mark_claims(const double* m, double amp, uint64_t bit, const uint64_t* want, int n,
                                    uint64_t* claims, uint64_t* maybe) {
  const V4d a = {amp, amp, amp, amp}, half = {0.5, 0.5, 0.5, 0.5};
  const V4u b = {bit, bit, bit, bit}, zero = {0, 0, 0, 0};
  V4u unclaimed = zero;
  for (int k = 0; k < n; k += kLanes) {
    TERRAIN_LOAD4(V4d, x, m + k);
    TERRAIN_LOAD4(V4u, c, claims + k);
    TERRAIN_LOAD4(V4u, may, maybe + k);
    TERRAIN_LOAD4(V4u, w, want + k);
    const V4u yes = V4u(x - a >= half), no = V4u(x + a < half);
    c |= yes & b;
    TERRAIN_STORE4(claims + k, c);
    TERRAIN_STORE4(maybe + k, may | (~(yes | no) & b));
    unclaimed -= V4u(c == zero) & w;  // each true lane is all ones: -1
  }
  return int(unclaimed[0] + unclaimed[1] + unclaimed[2] + unclaimed[3]);
}
#undef TERRAIN_LOAD4
#undef TERRAIN_STORE4
}  // namespace

void choose_materials_row(const MaterialRules& rules, const SampleRow* per_scale, const double* x_m, double y_m,
                          double min_noise_wavelength_m, int n, const uint8_t* wanted, uint8_t* out) {
  const size_t count = rules.rules.size();
  if (count > 64) {  // the bit sets below hold 64 rules; longer files go a sample at a time
    for (int k = 0; k < n; ++k) {
      SurfaceSample s[kMaxRuleScales];
      for (size_t c = 0; c < rules.scales.size(); ++c) {
        const SampleRow& row = per_scale[c];
        s[c].x_m = x_m[k];
        s[c].y_m = y_m;
        s[c].min_noise_wavelength_m = min_noise_wavelength_m;
        s[c].height_m = row.height_m[k];
        s[c].slope_deg = row.slope_deg[k];
        if (row.curvature) s[c].curvature = row.curvature[k];
        if (row.aspect_deg) s[c].aspect_deg = row.aspect_deg[k];
      }
      out[k] = choose_material_scaled(rules, s);
    }
    return;
  }
  // Per rule, its mask over the row and which samples it claims outright (mask - amplitude >= 0.5)
  // or may claim (in the noise band); rule_matches' tests on the same doubles.
  static thread_local std::vector<double> masks;
  masks.resize(count * kMaxRowSamples);
  alignas(32) uint64_t claims[kMaxRowSamples] = {}, maybe[kMaxRowSamples] = {}, want[kMaxRowSamples] = {};
  for (int k = 0; k < n; ++k) want[k] = !wanted || wanted[k] ? ~uint64_t(0) : 0;
  for (size_t ri = 0; ri < count; ++ri) {
    const MaterialRule& r = rules.rules[ri];
    const SampleRow& row = per_scale[r.scale_index];
    double* m = masks.data() + ri * kMaxRowSamples;
    range_mask_row(r.height_m, row.height_m, n, true, m);
    range_mask_row(r.slope_deg, row.slope_deg, n, false, m);
    range_mask_row(r.curvature, row.curvature, n, false, m);
    aspect_mask_row(r.aspect_deg, row.aspect_deg, row.slope_deg, n, m);
    if (mark_claims(m, r.noise.amplitude, uint64_t(1) << ri, want, n, claims, maybe) == 0)
      break;  // later rules cannot change a choice (the sea's rows: after water)
  }
  // The first rule in priority order that claims the sample: an outright claim, unless a rule
  // before it claims it through its noise. open[k]: the rules before the first outright claim that
  // may still claim sample k through their noise.
  uint64_t open[kMaxRowSamples], any_open = 0;
  for (int k = 0; k < n; ++k) {
    const uint64_t first = claims[k] & (~claims[k] + 1);
    open[k] = want[k] & maybe[k] & (first ? first - 1 : ~uint64_t(0));
    any_open |= open[k];
    out[k] = first ? rules.rules[size_t(std::countr_zero(first))].material : rules.default_material;
  }
  // The noise rule by rule, for the samples still open to it (a row's noise at once: noise.h): a
  // sample takes the first rule whose noise lifts its mask to 0.5, as rule_matches in order would.
  static thread_local std::vector<NoiseRowTables> tables;
  tables.resize(count);
  int idx[kMaxRowSamples];
  double noise[kMaxRowSamples];
  while (any_open) {
    const size_t ri = size_t(std::countr_zero(any_open));
    const uint64_t bit = uint64_t(1) << ri;
    any_open &= any_open - 1;
    int listed = 0;
    for (int k = 0; k < n; ++k)
      if (open[k] & bit) idx[listed++] = k;
    if (listed == 0) continue;
    const MaterialRule& r = rules.rules[ri];
    fbm_noise_row(x_m, idx, listed, y_m, r.noise.scale_m, r.noise.octaves, r.noise.seed, min_noise_wavelength_m,
                  tables[ri], noise);
    const double* m = masks.data() + ri * kMaxRowSamples;
    for (int i = 0; i < listed; ++i) {
      const int k = idx[i];
      if (m[k] + r.noise.amplitude * noise[i] >= 0.5) {
        out[k] = r.material;
        open[k] = 0;  // decided: later rules' noise no longer matters
      }
    }
  }
}

Status parse_material_rules(const std::string& json_text, const std::string& origin, MaterialRules& out) {
  json doc;
  try {
    doc = json::parse(json_text);
  } catch (const json::parse_error& e) {
    return bad(origin, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) return bad(origin, "the document must be a JSON object");
  if (Status s = check_keys(doc, {"format", "version", "materials", "default_material", "scale_m", "despeckle", "band_limit_noise",
                               "rules"}, origin, "top level");
      !s.ok())
    return s;
  if (!doc.contains("format") || doc["format"] != "terrain-material-rules")
    return bad(origin, "\"format\" must be \"terrain-material-rules\"");
  if (!doc.contains("version") || !doc["version"].is_number_integer() || doc["version"].get<int>() != 1)
    return bad(origin, "\"version\" must be 1 (the only version this cooker reads)");
  if (!doc.contains("materials") || !doc["materials"].is_array() || doc["materials"].empty() ||
      doc["materials"].size() > 256)
    return bad(origin, "\"materials\" must be an array of 1..256 materials");

  MaterialRules rules;
  rules.source = origin;
  std::set<std::string> names;
  for (size_t i = 0; i < doc["materials"].size(); ++i) {
    const json& m = doc["materials"][i];
    const std::string w = "materials[" + std::to_string(i) + "]";
    if (!m.is_object()) return bad(origin, w + " must be an object");
    if (Status s = check_keys(m, {"name", "albedo_srgb", "roughness", "detail_scale_m", "detail_strength", "height_blend"},
                              origin, w);
        !s.ok())
      return s;
    Material mat;
    if (!m.contains("name") || !m["name"].is_string()) return bad(origin, w + ": \"name\" (string) is required");
    mat.name = m["name"].get<std::string>();
    if (mat.name.empty() || mat.name.size() > 31) return bad(origin, w + ": name must be 1..31 bytes");
    if (!names.insert(mat.name).second) return bad(origin, w + ": duplicate material name \"" + mat.name + "\"");
    if (!m.contains("albedo_srgb") || !m["albedo_srgb"].is_array() || m["albedo_srgb"].size() != 3)
      return bad(origin, w + ": \"albedo_srgb\" must be [r, g, b] with 0..255 integers");
    for (int c = 0; c < 3; ++c) {
      const json& v = m["albedo_srgb"][size_t(c)];
      if (!v.is_number_integer() || v.get<int>() < 0 || v.get<int>() > 255)
        return bad(origin, w + ": \"albedo_srgb\" must be [r, g, b] with 0..255 integers");
      mat.albedo_srgb[size_t(c)] = uint8_t(v.get<int>());
    }
    double d = mat.roughness;
    if (Status s = read_number(m, "roughness", 0, 1, d, origin, w); !s.ok()) return s;
    mat.roughness = float(d);
    d = mat.detail_scale_m;
    if (Status s = read_number(m, "detail_scale_m", 1e-3, 1e4, d, origin, w); !s.ok()) return s;
    mat.detail_scale_m = float(d);
    d = mat.detail_strength;
    if (Status s = read_number(m, "detail_strength", 0, 1, d, origin, w); !s.ok()) return s;
    mat.detail_strength = float(d);
    d = mat.height_blend;
    if (Status s = read_number(m, "height_blend", 0, 1, d, origin, w); !s.ok()) return s;
    mat.height_blend = float(d);
    rules.palette.push_back(mat);
  }
  auto index_of = [&](const json& v, uint8_t& idx) {
    if (!v.is_string()) return false;
    for (size_t i = 0; i < rules.palette.size(); ++i)
      if (rules.palette[i].name == v.get<std::string>()) {
        idx = uint8_t(i);
        return true;
      }
    return false;
  };
  if (!doc.contains("default_material") || !index_of(doc["default_material"], rules.default_material))
    return bad(origin, "\"default_material\" must name one of the materials");
  if (Status s = read_number(doc, "scale_m", 0, 1000, rules.scale_m, origin, "top level"); !s.ok()) return s;
  if (doc.contains("despeckle")) {
    if (!doc["despeckle"].is_boolean()) return bad(origin, "top level: \"despeckle\" must be true or false");
    rules.despeckle = doc["despeckle"].get<bool>();
  }
  if (doc.contains("band_limit_noise")) {
    if (!doc["band_limit_noise"].is_boolean())
      return bad(origin, "top level: \"band_limit_noise\" must be true or false");
    rules.band_limit_noise = doc["band_limit_noise"].get<bool>();
  }
  if (doc.contains("rules")) {
    if (!doc["rules"].is_array()) return bad(origin, "\"rules\" must be an array");
    for (size_t i = 0; i < doc["rules"].size(); ++i) {
      const json& r = doc["rules"][i];
      const std::string w = "rules[" + std::to_string(i) + "]";
      if (!r.is_object()) return bad(origin, w + " must be an object");
      if (Status s = check_keys(r, {"material", "scale_m", "height_m", "slope_deg", "curvature", "aspect_deg", "noise"},
                                origin, w);
          !s.ok())
        return s;
      MaterialRule rule;
      if (!r.contains("material") || !index_of(r["material"], rule.material))
        return bad(origin, w + ": \"material\" must name one of the materials");
      rule.scale_m = rules.scale_m;
      if (Status s = read_number(r, "scale_m", 0, 1000, rule.scale_m, origin, w); !s.ok()) return s;
      const auto known = std::find(rules.scales.begin(), rules.scales.end(), rule.scale_m);
      if (known == rules.scales.end()) {
        if (rules.scales.size() == kMaxRuleScales)
          return bad(origin, w + ": more than " + std::to_string(kMaxRuleScales) + " distinct \"scale_m\" values");
        rules.scales.push_back(rule.scale_m);
      }
      rule.scale_index = uint8_t(std::find(rules.scales.begin(), rules.scales.end(), rule.scale_m) - rules.scales.begin());
      if (Status s = read_range(r, "height_m", -20000, 20000, rule.height_m, origin, w); !s.ok()) return s;
      if (Status s = read_range(r, "slope_deg", 0, 90, rule.slope_deg, origin, w); !s.ok()) return s;
      if (Status s = read_range(r, "curvature", -1e3, 1e3, rule.curvature, origin, w); !s.ok()) return s;
      if (Status s = read_range(r, "aspect_deg", 0, 360, rule.aspect_deg, origin, w); !s.ok()) return s;
      if (rule.aspect_deg.active && (!std::isfinite(rule.aspect_deg.lo) || !std::isfinite(rule.aspect_deg.hi)))
        return bad(origin, w + ".aspect_deg needs both \"min\" and \"max\" (the arc may wrap: min > max)");
      if (r.contains("noise")) {
        const json& n = r["noise"];
        if (!n.is_object()) return bad(origin, w + ".noise must be an object");
        if (Status s = check_keys(n, {"amplitude", "scale_m", "octaves", "seed"}, origin, w + ".noise"); !s.ok())
          return s;
        if (Status s = read_number(n, "amplitude", 0, 10, rule.noise.amplitude, origin, w + ".noise"); !s.ok())
          return s;
        if (Status s = read_number(n, "scale_m", 1e-3, 1e6, rule.noise.scale_m, origin, w + ".noise"); !s.ok())
          return s;
        double oct = rule.noise.octaves, seed = 0;
        if (Status s = read_number(n, "octaves", 1, 8, oct, origin, w + ".noise"); !s.ok()) return s;
        if (Status s = read_number(n, "seed", 0, 4294967295.0, seed, origin, w + ".noise"); !s.ok()) return s;
        if (oct != std::floor(oct) || seed != std::floor(seed))
          return bad(origin, w + ".noise: \"octaves\" and \"seed\" must be integers");
        rule.noise.octaves = int(oct);
        rule.noise.seed = uint32_t(seed);
      }
      rules.rules.push_back(rule);
    }
  }
  out = std::move(rules);
  return Status::success();
}

MaterialRules default_material_rules() {
  MaterialRules rules;
  const Status s = parse_material_rules(kDefaultRulesJson, "built-in", rules);
  (void)s;  // the built-in document is covered by a test; it cannot fail at run time
  return rules;
}

std::string default_rules_json() { return kDefaultRulesJson; }

Status load_material_rules(const SurfaceOptions& options, std::shared_ptr<const MaterialRules>& out) {
  auto rules = std::make_shared<MaterialRules>();
  if (options.materials_path.empty()) {
    *rules = default_material_rules();
  } else {
    std::ifstream in(options.materials_path, std::ios::binary);
    if (!in) return Status::failure(Error::io_open, "cannot open material rules file " + options.materials_path);
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) return Status::failure(Error::io_read, "cannot read material rules file " + options.materials_path);
    if (Status s = parse_material_rules(text.str(), options.materials_path, *rules); !s.ok()) return s;
  }
  out = std::move(rules);
  return Status::success();
}

const std::vector<Material>& palette_of(const MaterialRules& rules) { return rules.palette; }

}  // namespace terrain::cook
