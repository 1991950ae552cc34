// Engine exports of an archive (terrain-export): heightmaps, material weight maps and hole masks for
// Unreal Landscape and for Godot (Terrain3D) / generic engines, plus a collision heightfield. Every
// height is read through SurfaceSampler (the surface terrain-inspect --sample answers), on a lattice
// of one level's vertex spacing. Light header: OpenImageIO stays inside the library.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/progress.h"
#include "terrain/status.h"

namespace terrain::engine_export {

enum class Target { unreal, godot };

// ---- Unreal size rule -------------------------------------------------------------------------
// Unreal's recommended landscape sizes (Landscape Technical Guide, "Recommended Landscape Sizes"):
// the heightmap side is components * quads_per_component + 1 with at most 32 components per side.
// With 63-quad sections, 2x2 per component (126 quads), 1..32 components: 126 * 2^k + 1 = 127 ..
// 4033; the largest, 8129, is 32 components of 2x2 127-quad sections (254 * 32 + 1). Sides of other
// sizes make Unreal resample or crop the import, so only these are written.
inline constexpr int kUnrealSizes[] = {127, 253, 505, 1009, 2017, 4033, 8129};
inline constexpr int kUnrealMaxSize = 8129;
bool is_unreal_size(int side);
// Smallest recommended side >= `samples`, or 0 when none is (then the export is tiled).
int unreal_size_for(int samples);

// Unreal maps a 16-bit value v to  z_cm = location_z_cm + (v - 32768) * z_scale / 128,  so Z scale
// 100 spans +-256 m (512 m). The export picks the smallest Z scale (rounded up to 1e-4) whose range
// holds the sampled heights around a centre location (rounded to 0.01 cm), then quantizes with the
// printed numbers: a re-import differs from the sampled surface by at most step_m / 2.
struct UnrealZ {
  double z_scale = 100;      // what to type into "Scale Z"
  double location_z_cm = 0;  // what to type into "Location Z"
  double step_m = 0;         // metres per 16-bit step = z_scale / 12800
};
UnrealZ unreal_z_for(double min_m, double max_m);
// A hole (no terrain) in an Unreal heightmap: unreal_encode never gives it (its values are 1..65535;
// the Z range reaches min_m at 1 or above), so cooking back with --nodata-value 0 restores the holes.
inline constexpr uint16_t kUnrealHoleValue = 0;
uint16_t unreal_encode(const UnrealZ& z, double height_m);
double unreal_decode(const UnrealZ& z, uint16_t v);

// ---- Options and plan -------------------------------------------------------------------------
struct Rect {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // frame metres
};

struct Options {
  Target target = Target::unreal;
  std::string out_dir;
  std::string name = "terrain";  // file name prefix: letters, digits, '-', '_'
  int level = -1;                // lattice spacing = vertex_spacing_m(level); -1: the finest level in the archive
  std::optional<Rect> rect;      // default: the archive's data extent
  // unreal: largest heightmap side before tiling (a kUnrealSizes entry; 0 = 8129).
  // godot: region side in samples (16..8192; 0 = 1024, Terrain3D's default region size).
  int tile_size = 0;
};

// The sample lattice and the files, known before any pixel is read (so the tool can check every
// output path against the archive first). Sample (col, row) is at frame point
// (west_x_m + col * spacing_m, north_y_m - row * spacing_m): row 0 is north, as in every image.
// The rectangle is widened to the level's vertex lattice (origin + k * spacing), so samples fall on
// archive vertices; samples past it (padding up to an Unreal size or a whole Godot region) are read
// from the archive too, and are holes where it has no terrain.
struct Plan {
  Options options;
  int level = 0;
  double spacing_m = 0;
  double west_x_m = 0, north_y_m = 0;
  int width = 0, height = 0;            // samples covering the rectangle
  int image_width = 0, image_height = 0;  // samples written (padded to whole tiles)
  // Tiles: tile (tx, ty) starts at sample (tx * tile_step, ty * tile_step). Unreal tiles share
  // their edge rows and columns (tile_step = tile_size - 1, World Partition "_x0_y0" import);
  // Godot regions do not (tile_step = tile_size, Terrain3D regions).
  int tile_size = 0, tile_step = 0, tiles_x = 1, tiles_y = 1;
  bool tiled = false;                   // file names carry _x<tx>_y<ty>
  std::vector<std::string> files;       // every file run_export may write (a superset)
};
Status plan_export(const ArchiveReader& reader, const Options& options, Plan& plan);

// The south-west sample of tile (tx, ty), frame metres: the --origin that cooks that tile's
// heightmap back where it came from (the JSON's cook_back.tiles and the printed commands carry it).
struct TileOrigin {
  double x_m = 0, y_m = 0;
};
TileOrigin tile_origin(const Plan& plan, int tx, int ty);

struct Result {
  std::vector<std::string> written;
  double min_height_m = 0, max_height_m = 0;  // over the sampled (non-hole) heights
  uint64_t samples = 0, hole_samples = 0;
  UnrealZ unreal;                             // unreal only
  std::vector<std::string> layers;            // materials with a weight map (present in the export)
  std::string json;                           // the <name>.json document also written
  std::vector<uint64_t> tile_hole_samples;    // per tile, row by row from the north-west tile
};
// Samples the lattice and writes the files (creating out_dir). `progress` may be empty; false from
// it cancels (Error::cancelled).
Status run_export(const ArchiveReader& reader, const Plan& plan, const ProgressFn& progress, Result& result);

// The text printed by terrain-export: what to type into the engine's import dialog, and one
// terrain-cook command per tile that cooks it back (its own origin; holes kept as holes).
std::string import_instructions(const Plan& plan, const Result& result);

}  // namespace terrain::engine_export
