#pragma once
// The stream of a recording's LiDAR, camera and label topics, one message at a time (for
// recording_input.cpp): scans with their per-point times, and images kept encoded (or as raw
// pixels) with T_lidar_camera at their stamp when the extrinsics move.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/sensors/sensor_input.hpp"
#include "slamvdb/sensors/tf_buffer.hpp"

namespace slamvdb {

// The topics the stream reads, by name (channel ids belong to one reader).
struct StreamTopics {
  std::string lidar, image, labels;
};

// "TOPIC message N", for messages and errors.
std::string recording_message_name(const recording::Message& m);

// The ids of the reader's channels on `topics`.
std::set<std::uint32_t> recording_channel_ids(const recording::RecordingReader& reader, const std::set<std::string>& topics);

// `lidar_camera`: the LiDAR-camera chain when it moves (each image gets T_lidar_camera at its
// stamp; an image outside tf's range is skipped and counted), which refers to `tf`, kept alive by
// the stream; nothing when the extrinsics are fixed.
std::unique_ptr<SensorStream> open_recording_stream(const std::filesystem::path& path, const StreamTopics& topics,
                                                    const InputOptions& options, const CameraModel& camera,
                                                    bool with_images, std::shared_ptr<const TfBuffer> tf,
                                                    std::optional<TfBuffer::Chain> lidar_camera);

}  // namespace slamvdb
