#pragma once
// The fleet's values read back from the text PostgreSQL gives them in (float8[] / real[] arrays,
// the fleet row's jsonb): a damaged or foreign value is an Error naming `what`, never another
// exception or a pose that is not rigid. No database here, so fuzz/fuzz_fleet_rows.cpp feeds them
// any bytes.
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fleet/fleet_pull.hpp"

namespace slamvdb::fleet {

// "{a,b,...}" with 16 finite numbers, row-major, a rigid transform (rotation orthonormal to 1e-6,
// last row 0 0 0 1).
Pose parse_pose_array(std::string_view text, const std::string& what);
// "{a,b,...}" of floats ("{}": none); NaN and infinities are refused.
std::vector<float> parse_real_array(std::string_view text, const std::string& what);
// The fleet row's params: a JSON object whose values are all strings.
std::map<std::string, std::string> parse_fleet_entries(std::string_view json, const std::string& what);
// The fleet's parameters and embedding space from its params ("(absent)" entries left out), the
// parameters validated as a map file's are.
FleetDefinition fleet_definition_of(std::string_view json, const std::string& what);

}  // namespace slamvdb::fleet
