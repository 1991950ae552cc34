// The example inputs in samples/: the material rules users start from parse, and
// samples/materials/default.json is the built-in rule set (same choice on every test sample), so the
// file people copy cannot drift from what a cook without --materials does.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "materials.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::cook;

namespace {

MaterialRules load_sample(const std::string& name) {
  const auto path = terrain::test::source_dir() / "samples" / "materials" / name;
  std::ifstream f(path);
  std::stringstream text;
  text << f.rdbuf();
  MaterialRules r;
  const Status st = parse_material_rules(text.str(), path.string(), r);
  EXPECT_TRUE(st.ok()) << st.to_string();
  return r;
}

// Counts the samples of a grid over height, slope, curvature, aspect and position whose material
// differs between two rule sets.
int differing_choices(const MaterialRules& a, const MaterialRules& b, int& total) {
  int differ = 0;
  total = 0;
  for (double h : {-5.0, 0.1, 2.0, 50.0, 900.0, 1500.0, 2100.0, 3100.0})
    for (double slope : {0.0, 4.0, 12.0, 30.0, 45.0, 60.0})
      for (double curv : {-0.03, 0.0, 0.01, 0.05})
        for (double aspect : {0.0, 180.0})
          for (double x : {0.0, 137.0, 5000.0}) {
            SurfaceSample s;
            s.x_m = x;
            s.y_m = 0.5 * x;
            s.height_m = h;
            s.slope_deg = slope;
            s.curvature = curv;
            s.aspect_deg = aspect;
            differ += choose_material(a, s) != choose_material(b, s);
            ++total;
          }
  return differ;
}

}  // namespace

TEST(Samples, DefaultMaterialsFileIsTheBuiltInRuleSet) {
  const MaterialRules file = load_sample("default.json"), builtin = default_material_rules();
  ASSERT_EQ(file.palette.size(), builtin.palette.size());
  for (size_t i = 0; i < file.palette.size(); ++i) {
    EXPECT_EQ(file.palette[i].name, builtin.palette[i].name);
    EXPECT_EQ(file.palette[i].albedo_srgb, builtin.palette[i].albedo_srgb);
  }
  int total = 0;
  EXPECT_EQ(differing_choices(file, builtin, total), 0) << "of " << total << " samples";
}

TEST(Samples, AridMaterialsParseAndChooseDifferently) {
  const MaterialRules arid = load_sample("arid.json"), builtin = default_material_rules();
  EXPECT_EQ(arid.palette[arid.default_material].name, "bare_soil");
  int total = 0;
  // Sand up to 900 m and forest only above 1200 m change a sizeable share of the grid.
  EXPECT_GT(differing_choices(arid, builtin, total), total / 20) << "of " << total << " samples";
}
