#pragma once
// Which topics of a recording slamvdb uses, and why: the LiDAR (PointCloud2), the camera (an image
// topic with a CameraInfo in its namespace: a LiDAR's own range or intensity images have none, so
// they are no camera), SIMULATED label images (an Image topic named "label"), poses (Odometry,
// PoseStamped, TransformStamped). Each is chosen automatically when there is exactly one candidate
// and the user named none; several candidates are a TopicChoiceError listing them and the options.
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

struct TopicSelection {
  const recording::Channel* lidar = nullptr;
  const recording::Channel* image = nullptr;        // null: no camera (geometry only)
  const recording::Channel* camera_info = nullptr;  // with image
  const recording::Channel* labels = nullptr;       // SIMULATED label images, optional
  const recording::Channel* poses = nullptr;        // optional
  std::vector<std::string> reasons;                 // one line per choice: "LiDAR: /points (the only PointCloud2 topic)"
};

// `want_poses`: choose a pose topic automatically when there is exactly one (and none was named).
// `want_camera`: choose the camera and label topics (not for odometry).
// `require_lidar`: no PointCloud2 topic is an Error (inspect lists what there is instead).
TopicSelection choose_topics(const std::vector<recording::Channel>& channels, const TopicChoice& choice,
                             bool want_poses, bool want_camera = true, bool require_lidar = true);

// The options that choose topics, for messages.
inline constexpr const char* kTopicOptions =
    "--lidar-topic, --image-topic, --camera-info-topic, --label-topic, --pose-topic";

}  // namespace slamvdb
