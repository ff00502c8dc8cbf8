#pragma once
// A robot recording as a SensorInput. Before the data, one pass over the small topics only
// (RecordingReader::select: CameraInfo, /tf_static and /tf, the pose topic) gives the camera,
// T_lidar_camera and the poses, and the first LiDAR message its frame; the stream then reads the
// LiDAR, camera and label topics, one message at a time.
#include <filesystem>
#include <memory>

#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

std::unique_ptr<SensorInput> open_recording_input(const std::filesystem::path& path, const InputOptions& options);

}  // namespace slamvdb
