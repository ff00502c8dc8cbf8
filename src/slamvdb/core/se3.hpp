#pragma once
// exp / log of SE(3) and geodesic interpolation, shared by trajectories (fusion) and the
// localization part (which must not depend on the map).
#include "slamvdb/core/types.hpp"

namespace slamvdb {

// exp / log of SE(3) with the twist ordered (rho, phi): translation part first.
using Twist = Eigen::Matrix<double, 6, 1>;
Pose se3_exp(const Twist& xi);
Twist se3_log(const Pose& T);
// Geodesic interpolation: T0 * exp(s * log(T0^-1 * T1)), s in [0, 1].
Pose interpolate_se3(const Pose& T0, const Pose& T1, double s);

}  // namespace slamvdb
