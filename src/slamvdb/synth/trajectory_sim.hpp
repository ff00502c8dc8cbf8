#pragma once
// The simulated drive: a smooth closed loop (the trail's centre line) that the vehicle follows,
// weaving a little within the trail, on the ground, past its start so it revisits a place.
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/synth/terrain.hpp"

namespace slamvdb::synth {

class LoopPath {
 public:
  // A seeded, star-shaped smooth loop through the origin with the given perimeter (metres),
  // driven counter-clockwise.
  LoopPath(double perimeter, uint64_t seed);

  double perimeter() const { return perimeter_; }
  Eigen::Vector2d point(double s) const;    // centre line at arc length s (wraps around)
  Eigen::Vector2d tangent(double s) const;  // unit
  Eigen::Vector2d left(double s) const;     // unit normal, pointing into the loop
  Eigen::Vector2d at(double s, double lateral) const { return point(s) + lateral * left(s); }
  double distance(const Eigen::Vector2d& p) const;  // to the centre line
  Eigen::AlignedBox2d bounds() const;

 private:
  double perimeter_ = 0.0;
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();
  // Polar shape r(th) = R (1 + a2 cos(2 th + p2) + a3 cos(3 th + p3)) around centre_.
  double radius_ = 1.0, a2_ = 0.0, a3_ = 0.0, phase2_ = 0.0, phase3_ = 0.0;
  std::vector<double> theta_of_s_;  // polar angle at evenly spaced arc lengths, one lap
  double ds_ = 0.0;
  std::vector<Eigen::Vector2d> samples_;  // centre line every ~0.5 m, for distance queries
  double theta(double s) const;
  Eigen::Vector2d curve(double th) const;
  Eigen::Vector2d curve_derivative(double th) const;
};

class SimulatedTrajectory {
 public:
  // LiDAR `sensor_height` above the ground, mounted turned 180 degrees about z (x backwards) as
  // RELLIS-3D's Ouster is; the body follows the terrain's roll and pitch over its footprint.
  // The drive starts `start_offset` metres along the loop and, when `reverse`, drives it clockwise.
  SimulatedTrajectory(LoopPath path, std::shared_ptr<const Terrain> terrain, double speed, double sensor_height,
                      double start_offset = 0.0, bool reverse = false);

  // Ground truth T_world_lidar at `elapsed` seconds after the start.
  Pose T_world_lidar(double elapsed) const;
  const LoopPath& path() const { return path_; }

 private:
  Pose T_world_body(double elapsed) const;  // x forward, y left, z up, origin on the ground
  double lateral_offset(double s) const;    // the driver's weave within the trail, at loop arc length s

  LoopPath path_;
  std::shared_ptr<const Terrain> terrain_;
  double speed_, sensor_height_;
  double start_offset_ = 0.0, direction_ = 1.0;  // loop arc length = start + direction x distance driven
};

}  // namespace slamvdb::synth
