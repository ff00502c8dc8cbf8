#pragma once
// Deskewing in mapping. A spinning LiDAR takes a scan over its sweep (0.1 s at 10 Hz) while the
// vehicle moves; fused from the scan's one pose, the points taken early or late in the sweep land
// where the sensor was not, and walls seen while turning come out smeared. A scan with per-point
// times is therefore moved into the sensor frame of one instant before the mapper fuses it, with
// the motion the mapping knows:
//   - `map` with poses (ground truth, --poses, --pose-topic, or --odometry's trajectory): the
//     trajectory itself, interpolated at each point's time (here), into the frame at the scan's
//     stamp, which is where the mapper places the scan. Interpolating the trajectory rather than
//     assuming constant velocity from the neighbouring scans uses every pose there is (a pose topic
//     at 100 Hz follows the motion within the sweep) and is the same thing for poses at the scans;
//     only beyond the trajectory's ends is the velocity of its first or last segment kept.
//   - `slam` and `map --odometry`: the odometry's own constant-velocity estimate that it deskewed
//     its registration points with (LidarTracker::last_sweep), into the mid-sweep frame its pose
//     refers to. (Interpolating the odometry's trajectory instead would deskew into the frame at
//     the stamp while the pose is the mid-sweep one: half a sweep's motion off.)
// The map itself knows nothing of it: it gets the scan already deskewed.
#include <map>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fusion/trajectory.hpp"
#include "slamvdb/localization/preprocessing.hpp"

namespace slamvdb {

// The odometry's deskewing motion per scan stamp (OdometryPoses::sweeps), for `map --odometry`.
using SweepMotions = std::map<double, localization::SweepMotion>;
// How the report names the motions: the poses' trajectory, or the odometry's.
inline constexpr const char* kTrajectoryDeskewMotion = "the poses, interpolated at each point's time";
inline constexpr const char* kOdometryDeskewMotion =
    "the odometry's constant-velocity estimate (none yet for the first two scans)";

// Moves `points` (with `times`, seconds relative to `stamp`) into the sensor frame at `stamp`
// with the trajectory's motion. False, the points unchanged, when the trajectory cannot say how
// the sensor moved then: fewer than two poses, or `stamp` outside them (the mapper counts such a
// scan as without a pose). Non-finite points stay as they are (the mapper counts them).
bool deskew_with_trajectory(const Trajectory& poses, double stamp, std::vector<Vec3f>& points,
                            const std::vector<float>& times);

// Moves `points` (with `times`) into the mid-sweep frame with the odometry's motion over the sweep.
void deskew_with_sweep(const localization::SweepMotion& sweep, std::vector<Vec3f>& points,
                       const std::vector<float>& times);

}  // namespace slamvdb
