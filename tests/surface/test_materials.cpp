// Material rules: the built-in palette, the JSON format and its errors, mask arithmetic and the
// rule evaluation.
#include <gtest/gtest.h>

#include <fstream>
#include <set>

#include "materials.h"
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
