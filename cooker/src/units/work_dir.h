// The names of a work dir's files (format/SPEC.md section 18): W/plan.json, W/inputs-<fingerprint>.json
// and, under W/units, per unit its file, its list of input files and its cut of a VRT input.
// work_dir_owns (terrain/cook.h) says which paths are the work dir's.
#pragma once
#include <cstdint>
#include <string>

namespace terrain::cook {

struct UnitPlan;

std::string plan_file(const std::string& work_dir);
std::string units_dir(const std::string& work_dir);  // <work_dir>/units: the unit files
// <work_dir>/inputs-<fingerprint>.json: every input file of the plan (plan.json names it).
std::string inputs_file(const std::string& work_dir, const std::string& fingerprint);
std::string unit_file(const std::string& work_dir, uint32_t index);
// The VRT a unit reads when the cook's one input is a VRT mosaic: the plan cuts it to the unit's
// window (write_vrt_windows, source_raster.h), named by the unit's fingerprint so that a cut is
// never one of another plan or window. A unit without one (an earlier version's plan, or not
// written) reads the input itself; the bytes are the same.
std::string unit_vrt_file(const std::string& work_dir, const UnitPlan& unit);
// A unit's list of the input files its window meets (those its fingerprint holds), named by its
// fingerprint: what `unit` reads of the inputs instead of the plan's whole list.
std::string unit_inputs_file(const std::string& work_dir, const UnitPlan& unit);

}  // namespace terrain::cook
