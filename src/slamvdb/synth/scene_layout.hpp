#pragma once
// The simulated off-road world laid out around a loop trail: an asphalt stretch by a building
// with a concrete pad, parked vehicles, barriers and poles at the start (the place the drive
// revisits), then a dirt trail with mud, puddles, rubble, a fence and logs through grass fields
// with trees and bushes.
#include <cstdint>

#include "slamvdb/synth/scene.hpp"
#include "slamvdb/synth/trajectory_sim.hpp"

namespace slamvdb::synth {

Scene build_offroad_scene(const LoopPath& path, uint64_t seed);

// Look-alike places: one arrangement of objects, fixed in the trail's frame, repeated every
// `spacing` metres along the loop on grass with a dirt trail (SceneKind::kRepeatedPlaces).
Scene build_repeated_places_scene(const LoopPath& path, uint64_t seed, double spacing);

}  // namespace slamvdb::synth
