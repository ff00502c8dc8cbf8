// The fleet's row parsers (fleet/fleet_rows.hpp): the text PostgreSQL gives a submap's anchor or a
// session's frame (float8[]), a submap's embedding centroid (real[]) and the fleet row's
// parameters (jsonb). The first byte picks the parser, the rest is the value. An accepted pose is
// rigid and finite, an accepted centroid finite, accepted parameters valid map parameters.
#include <cmath>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_rows.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    switch (data[0] % 3) {
      case 0: {
        const slamvdb::Pose T = slamvdb::fleet::parse_pose_array(text, "anchor");
        const Eigen::Matrix3d R = T.linear();
        if (!T.matrix().allFinite() || !((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() <= 1e-6))
          __builtin_trap();
        break;
      }
      case 1:
        for (const float v : slamvdb::fleet::parse_real_array(text, "centroid"))
          if (!std::isfinite(v)) __builtin_trap();
        break;
      default: {
        const slamvdb::fleet::FleetDefinition d = slamvdb::fleet::fleet_definition_of(text, "fleet");
        if (!(d.params.occupancy.voxel_size > 0) || d.params.semantic.dim <= 0) __builtin_trap();
      }
    }
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
