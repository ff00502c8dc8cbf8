#pragma once
// Basic geometric types shared by every part of slamvdb.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace slamvdb {

using Vec3f = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;
using Pose = Eigen::Isometry3d;  // rigid transform; T_a_b maps points from frame b into frame a

// Integer voxel coordinates. 32-bit per axis: at 0.25 m this spans +-536 000 km, so the map is
// effectively unbounded (OctoMap's 16-bit keys stop at +-8 km).
using VoxelKey = Eigen::Vector3i;

struct VoxelKeyHash {
  std::size_t operator()(const VoxelKey& k) const noexcept {
    // Large primes as in Teschner et al. 2003 (spatial hashing); cheap and well spread.
    return static_cast<std::size_t>(static_cast<uint64_t>(static_cast<uint32_t>(k.x())) * 73856093ULL ^
                                    static_cast<uint64_t>(static_cast<uint32_t>(k.y())) * 19349669ULL ^
                                    static_cast<uint64_t>(static_cast<uint32_t>(k.z())) * 83492791ULL);
  }
};

// A LiDAR scan in the sensor frame with optional per-point class labels (RELLIS-3D ids).
struct LidarScan {
  double stamp = 0.0;                // seconds
  std::vector<Vec3f> points;         // sensor frame
  std::vector<float> intensity;      // same length as points, or empty
  std::vector<uint16_t> labels;      // same length as points, or empty
};

}  // namespace slamvdb
