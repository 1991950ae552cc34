// Material rules: the built-in palette, the JSON format and its errors, mask arithmetic and the
// rule evaluation.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <fstream>
#include <limits>
#include <random>
#include <set>

#include "materials.h"
#include "noise.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::cook;

namespace {
// An active mask range lo .. hi with a `fade`-wide ramp, inv_fade set as the parser sets it.
MaskRange active_range(double lo, double hi, double fade) {
  MaskRange m;
  m.active = true;
  m.lo = lo;
  m.hi = hi;
  m.fade = fade;
  m.inv_fade = fade > 0 ? 1.0 / fade : 0.0;
  return m;
}
}  // namespace

TEST(Materials, BuiltInPaletteCoversRealLandscapes) {
  const MaterialRules r = default_material_rules();
  std::set<std::string> names;
  for (const Material& m : r.palette) names.insert(m.name);
  for (const char* want : {"rock", "scree", "grass", "forest_floor", "snow", "sand", "mud", "water"})
    EXPECT_TRUE(names.count(want)) << want;
  EXPECT_GE(r.rules.size(), 8u);
  EXPECT_EQ(r.palette[r.default_material].name, "grass");
  for (const Material& m : r.palette) {
    EXPECT_GE(m.roughness, 0.0f);
    EXPECT_LE(m.roughness, 1.0f);
    EXPECT_LE(m.name.size(), 31u);
  }
}

TEST(Materials, DefaultJsonRoundTripsThroughTheParser) {
  MaterialRules a, b = default_material_rules();
  ASSERT_TRUE(parse_material_rules(default_rules_json(), "copy", a).ok());
  ASSERT_EQ(a.palette.size(), b.palette.size());
  ASSERT_EQ(a.rules.size(), b.rules.size());
  for (size_t i = 0; i < a.palette.size(); ++i) EXPECT_EQ(a.palette[i].albedo_srgb, b.palette[i].albedo_srgb);
}

TEST(Materials, LoadsAFileAndNamesMissingFiles) {
  const auto dir = terrain::test::scratch_dir("materials");
  const auto path = dir / "rules.json";
  std::ofstream(path) << R"({"format": "terrain-material-rules", "version": 1,
    "materials": [{"name": "a", "albedo_srgb": [1, 2, 3]}, {"name": "b", "albedo_srgb": [4, 5, 6]}],
    "default_material": "b",
    "rules": [{"material": "a", "height_m": {"min": 100}}]})";
  SurfaceOptions opt;
  opt.materials_path = path.string();
  std::shared_ptr<const MaterialRules> rules;
  ASSERT_TRUE(load_material_rules(opt, rules).ok());
  EXPECT_EQ(palette_of(*rules).size(), 2u);
  SurfaceSample s;
  s.height_m = 150;
  EXPECT_EQ(choose_material(*rules, s), 0);
  s.height_m = 50;
  EXPECT_EQ(choose_material(*rules, s), 1);

  opt.materials_path = (dir / "missing.json").string();
  const Status st = load_material_rules(opt, rules);
  EXPECT_EQ(st.code, Error::io_open);
  EXPECT_NE(st.message.find("missing.json"), std::string::npos);
}

TEST(Materials, ParseErrorsNameTheProblem) {
  struct Case {
    std::string json;
    const char* must_mention;
  };
  const std::string head = R"({"format": "terrain-material-rules", "version": 1, "materials": [{"name": "a", "albedo_srgb": [1, 2, 3]}], "default_material": "a")";
  const Case cases[] = {
      {"{", "not valid JSON"},
      {R"({"format": "x", "version": 1})", "format"},
      {R"({"format": "terrain-material-rules", "version": 2, "materials": []})", "version"},
      {head + R"(, "rules": [{"material": "zzz"}]})", "rules[0]"},
      {head + R"(, "rules": [{"material": "a", "slope": {"min": 3}}]})", "unknown key \"slope\""},
      {head + R"(, "rules": [{"material": "a", "slope_deg": {"min": 120}}]})", "slope_deg"},
      {head + R"(, "rules": [{"material": "a", "height_m": {"min": 1, "fade": -2}}]})", "fade"},
      {head + R"(, "rules": [{"material": "a", "aspect_deg": {"min": 10}}]})", "aspect_deg"},
      {R"({"format": "terrain-material-rules", "version": 1, "materials": [{"name": "a", "albedo_srgb": [1, 2, 300]}], "default_material": "a"})",
       "albedo_srgb"},
      {R"({"format": "terrain-material-rules", "version": 1, "materials": [{"name": "a", "albedo_srgb": [1, 2, 3]}, {"name": "a", "albedo_srgb": [1, 2, 3]}], "default_material": "a"})",
       "duplicate"},
  };
  for (const Case& c : cases) {
    MaterialRules r;
    const Status st = parse_material_rules(c.json, "test.json", r);
    EXPECT_EQ(st.code, Error::invalid_argument) << c.json;
    EXPECT_NE(st.message.find(c.must_mention), std::string::npos) << st.message;
    EXPECT_NE(st.message.find("test.json"), std::string::npos) << st.message;
  }
}

TEST(Materials, MaskIsOneHalfAtTheBoundsAndLinearInTheFade) {
  MaskRange m = active_range(10, 20, 4);
  EXPECT_DOUBLE_EQ(mask_value(m, 10), 0.5);
  EXPECT_DOUBLE_EQ(mask_value(m, 20), 0.5);
  EXPECT_DOUBLE_EQ(mask_value(m, 15), 1.0);
  EXPECT_DOUBLE_EQ(mask_value(m, 9), 0.25);
  EXPECT_DOUBLE_EQ(mask_value(m, 7), 0.0);
  m.fade = m.inv_fade = 0;  // hard step
  EXPECT_EQ(mask_value(m, 9.999), 0.0);
  EXPECT_EQ(mask_value(m, 10), 1.0);
}

TEST(Materials, AspectRangesWrapAroundNorth) {
  MaskRange m = active_range(300, 60, 0);  // north-facing: 300 .. 60 through 0
  EXPECT_EQ(aspect_mask_value(m, 0), 1.0);
  EXPECT_EQ(aspect_mask_value(m, 359), 1.0);
  EXPECT_EQ(aspect_mask_value(m, 59), 1.0);
  EXPECT_EQ(aspect_mask_value(m, 180), 0.0);
  m = active_range(300, 60, 20);
  EXPECT_DOUBLE_EQ(aspect_mask_value(m, 300), 0.5);
  EXPECT_DOUBLE_EQ(aspect_mask_value(m, 290), 0.0);
  EXPECT_DOUBLE_EQ(aspect_mask_value(m, 70), 0.0);
  EXPECT_DOUBLE_EQ(aspect_mask_value(m, 65), 0.25);
}

TEST(Materials, DefaultRulesPickPlausibleMaterials) {
  const MaterialRules r = default_material_rules();
  auto name = [&](double h, double slope, double curv, double aspect) {
    SurfaceSample s;
    s.x_m = 1234.5;
    s.y_m = 987.25;
    s.height_m = h;
    s.slope_deg = slope;
    s.curvature = curv;
    s.aspect_deg = aspect;
    return r.palette[choose_material(r, s)].name;
  };
  EXPECT_EQ(name(0.0, 0.5, 0, 0), "water");
  EXPECT_EQ(name(1.5, 4, 0, 0), "sand");
  EXPECT_EQ(name(3500, 10, 0, 0), "snow");
  EXPECT_EQ(name(800, 70, 0, 90), "cliff");
  EXPECT_EQ(name(3500, 70, 0, 90), "cliff");  // too steep for snow to stick
  EXPECT_EQ(name(800, 45, -0.01, 90), "rock");
}

TEST(Materials, RuleEvaluationIsAPureFunctionOfTheSample) {
  const MaterialRules r = default_material_rules();
  SurfaceSample s;
  int changes = 0;
  uint8_t last = 255;
  for (int i = 0; i < 2000; ++i) {
    s.x_m = 1000 + i * 0.5;
    s.y_m = 2000;
    s.height_m = 1800;  // inside forest's height fade: the noise decides
    s.slope_deg = 12;
    const uint8_t a = choose_material(r, s), b = choose_material(r, s);
    ASSERT_EQ(a, b);
    if (a != last && last != 255) ++changes;
    last = a;
  }
  // Noise-perturbed transitions: along 1 km the choice flips, but not at every sample (the noise
  // has a 90 m wavelength).
  EXPECT_GT(changes, 2);
  EXPECT_LT(changes, 200);
}

// choose_materials_row (a row's masks in vector loops, noise only where it can decide) against
// choose_material_scaled, sample for sample: random rule sets (hard and soft ranges, open ends,
// aspect arcs that wrap and bounds outside 0..360, zero and non-zero noise, 1..3 scales, and one
// file of 70 rules for the fallback) on samples placed on each rule's bounds, fade ends and the
// 1-degree aspect cut, plus NaN and aspects outside 0..360.
TEST(Materials, RowChoiceEqualsThePerSampleChoice) {
  std::mt19937_64 rng(20261204);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto chance = [&](double p) { return uni(0, 1) < p; };
  auto range = [&](double lo_min, double hi_max) {
    MaskRange m;
    if (!chance(0.6)) return m;
    const double a = uni(lo_min, hi_max), b = uni(lo_min, hi_max);
    return active_range(chance(0.15) ? -std::numeric_limits<double>::infinity() : std::min(a, b),
                        chance(0.15) ? std::numeric_limits<double>::infinity() : std::max(a, b),
                        chance(0.3) ? 0.0 : uni(0.001, (hi_max - lo_min) * 0.3));
  };
  // A value on one of the range's edges (bound, fade end, middle), or anywhere in [lo, hi].
  auto near_edge = [&](const MaskRange& m, double lo, double hi) {
    if (!m.active || chance(0.3)) return uni(lo, hi);
    const double e[6] = {m.lo, m.hi, m.lo - m.fade / 2, m.hi + m.fade / 2, m.lo + m.fade / 2, (m.lo + m.hi) / 2};
    const double v = e[std::uniform_int_distribution<int>(0, 5)(rng)];
    return std::isfinite(v) ? v : uni(lo, hi);
  };
  long samples = 0, outright = 0, by_noise = 0, defaulted = 0, fallback_samples = 0;
  for (int trial = 0; trial < 400; ++trial) {
    MaterialRules rules;
    rules.palette.resize(80);
    rules.default_material = uint8_t(std::uniform_int_distribution<int>(70, 79)(rng));  // no rule's
    const size_t scales = size_t(std::uniform_int_distribution<int>(1, 3)(rng));
    for (size_t s = 0; s < scales; ++s) rules.scales.push_back(double(s + 1));
    const int count = trial == 0 ? 70 : std::uniform_int_distribution<int>(1, 12)(rng);
    for (int i = 0; i < count; ++i) {
      MaterialRule r;
      r.material = uint8_t(i);
      r.height_m = range(-50, 3000);
      r.slope_deg = range(0, 90);
      r.curvature = range(-0.05, 0.05);
      r.aspect_deg = range(-400, 400);
      if (r.aspect_deg.active && !std::isfinite(r.aspect_deg.lo)) r.aspect_deg.lo = uni(0, 360);
      if (r.aspect_deg.active && !std::isfinite(r.aspect_deg.hi)) r.aspect_deg.hi = uni(0, 360);
      r.noise.amplitude = chance(0.3) ? 0.0 : uni(0.01, 0.5);
      r.noise.scale_m = uni(5, 100);
      r.noise.octaves = std::uniform_int_distribution<int>(1, 3)(rng);
      r.noise.seed = uint32_t(rng());
      r.scale_index = uint8_t(std::uniform_int_distribution<int>(0, int(scales) - 1)(rng));
      rules.rules.push_back(r);
    }
    const int n = trial % 2 ? kMaxRowSamples : std::uniform_int_distribution<int>(1, kMaxRowSamples)(rng);
    const double y = uni(-1e6, 1e6), band = chance(0.5) ? 0.0 : uni(1, 8);
    double attr[kMaxRuleScales][4][kMaxRowSamples], x[kMaxRowSamples];
    // Half the trials place the samples as a lattice row does (evenly, far from the origin), where
    // the noise comes from the row's lattice tables; the others anywhere (fbm_noise per sample).
    const bool row_like = trial % 2 == 0;
    const double x0 = uni(-1e7, 1e7), spacing = uni(0.25, 20);
    for (int k = 0; k < n; ++k) {
      x[k] = row_like ? x0 + k * spacing : uni(-1e6, 1e6);
      // Each attribute aims at the edges of a random rule's range.
      for (size_t s = 0; s < scales; ++s) {
        const MaterialRule& r = rules.rules[size_t(std::uniform_int_distribution<int>(0, count - 1)(rng))];
        attr[s][0][k] = near_edge(r.height_m, -50, 3000);
        attr[s][1][k] = chance(0.1) ? (chance(0.5) ? 1.0 : std::nextafter(1.0, 0.0)) : near_edge(r.slope_deg, 0, 90);
        attr[s][2][k] = near_edge(r.curvature, -0.05, 0.05);
        attr[s][3][k] = chance(0.1) ? (chance(0.5) ? 360.0 : uni(-720, 720)) : near_edge(r.aspect_deg, 0, 360);
        if (chance(0.02)) attr[s][std::uniform_int_distribution<int>(0, 3)(rng)][k] = std::nan("");
      }
    }
    SampleRow rows[kMaxRuleScales];
    for (size_t s = 0; s < scales; ++s) rows[s] = SampleRow{attr[s][0], attr[s][1], attr[s][2], attr[s][3]};
    // Every third trial uses only a random half of the row (the others' choices are unspecified).
    uint8_t wanted[kMaxRowSamples];
    for (int k = 0; k < n; ++k) wanted[k] = trial % 3 != 2 || chance(0.5);
    uint8_t got[kMaxRowSamples];
    choose_materials_row(rules, rows, x, y, band, n, trial % 3 == 2 ? wanted : nullptr, got);
    for (int k = 0; k < n; ++k) {
      if (!wanted[k]) continue;
      SurfaceSample per_scale[kMaxRuleScales];
      for (size_t s = 0; s < scales; ++s)
        per_scale[s] = SurfaceSample{x[k], y, attr[s][0][k], attr[s][1][k], attr[s][2][k], attr[s][3][k], band};
      const uint8_t want = choose_material_scaled(rules, per_scale);
      ASSERT_EQ(got[k], want) << "trial " << trial << " sample " << k;
      ++samples;
      fallback_samples += count > 64;
      if (want == rules.default_material) {
        ++defaulted;
        continue;
      }
      // How the winning rule decided (the mask as rule_matches computes it, from the public masks).
      const MaterialRule& r = rules.rules[want];
      const SurfaceSample& s = per_scale[r.scale_index];
      double m = mask_value(r.height_m, s.height_m);
      if (m > 0) m *= mask_value(r.slope_deg, s.slope_deg);
      if (m > 0) m *= mask_value(r.curvature, s.curvature);
      if (m > 0 && s.slope_deg >= 1.0) m *= aspect_mask_value(r.aspect_deg, s.aspect_deg);
      if (m - r.noise.amplitude >= 0.5) ++outright;
      else ++by_noise;
    }
  }
  EXPECT_GT(fallback_samples, 0);
  EXPECT_GT(outright, samples / 10);
  EXPECT_GT(by_noise, samples / 20);
  EXPECT_GT(defaulted, samples / 20);
  std::printf("%ld samples equal: %ld claimed outright, %ld through noise, %ld default\n", samples, outright, by_noise,
              defaulted);
}

// fbm_noise_row (a row's noise from per-octave lattice tables, kept across rows) against
// fbm_noise, bit for bit: rows of 1..300 points at 0.1-40 m spacings anywhere within 1e7 m of the
// origin, walked up in y so tables are kept and rebuilt, random subsets in random order, 1..8
// octaves, band limits; then points where the tables cannot serve (spans of more than the table's
// cells, coordinates beyond 2^52 lattice units), which fbm_noise itself answers. (Non-finite
// coordinates are outside fbm_noise's domain: its floor converts to int64.)
TEST(Noise, RowGivesEveryPointTheBitsOfFbmNoise) {
  std::mt19937_64 rng(20261204);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto same = [](double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  long points = 0, unusual = 0;
  for (int trial = 0; trial < 300; ++trial) {
    NoiseRowTables tables;
    // Every fourth trial puts points and rows on lattice lines (power-of-two scales, spacings of a
    // quarter cell from a whole cell): the floors of exact integers.
    const bool on_lines = trial % 4 == 1;
    const double cell = std::ldexp(1.0, std::uniform_int_distribution<int>(0, 7)(rng));
    const double scale = on_lines ? cell : uni(1, 120);
    const double x0 = on_lines ? cell * std::round(uni(-1e5, 1e5)) : uni(-1e7, 1e7);
    const double spacing = on_lines ? cell / 4 : uni(0.1, 40);
    const int octaves = std::uniform_int_distribution<int>(1, 8)(rng);
    const uint32_t seed = uint32_t(rng());
    const double band = trial % 3 == 0 ? 0.0 : uni(0.2, 60);
    const int n = std::uniform_int_distribution<int>(1, 300)(rng);
    std::vector<double> x(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) x[size_t(k)] = x0 + k * spacing;
    const bool odd_points = trial % 10 == 9;
    if (odd_points) {
      const double odd[3] = {1e15, -1e15, x0 + 1e6};
      for (int i = 0; i < 1 + n / 20; ++i)
        x[size_t(std::uniform_int_distribution<int>(0, n - 1)(rng))] = odd[std::uniform_int_distribution<int>(0, 2)(rng)];
    }
    double y = on_lines ? cell * std::round(uni(-1e5, 1e5)) : uni(-1e7, 1e7);
    for (int row = 0; row < 8; ++row, y += on_lines ? spacing : uni(0, 3 * spacing)) {
      std::vector<int> idx;
      for (int k = 0; k < n; ++k)
        if (row % 2 == 0 || uni(0, 1) < 0.4) idx.push_back(k);
      if (row % 4 == 3) std::shuffle(idx.begin(), idx.end(), rng);
      std::vector<double> got(idx.size() + 1);
      const bool all = row == 0;
      fbm_noise_row(x.data(), all ? nullptr : idx.data(), int(idx.size()), y, scale, octaves, seed, band, tables,
                    got.data());
      for (size_t i = 0; i < idx.size(); ++i) {
        const double xi = x[size_t(idx[i])];
        const double want = fbm_noise(xi, y, scale, octaves, seed, band);
        ASSERT_TRUE(same(got[i], want)) << "trial " << trial << " row " << row << " x " << xi << ": " << got[i]
                                        << " against " << want;
        ++points;
        unusual += odd_points && (std::fabs(xi) == 1e15 || xi == x0 + 1e6);
      }
    }
  }
  EXPECT_GT(points, 200000);
  EXPECT_GT(unusual, 100);
}
