#include "slamvdb/sensors/recording_topics.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <functional>

#include "slamvdb/recording/messages.hpp"

namespace slamvdb {

namespace {

using recording::Channel;
using recording::MessageKind;
using ChannelList = std::vector<const Channel*>;

MessageKind kind_of(const Channel& c) { return recording::message_kind(c.type); }
bool is_image(const Channel& c) {
  return kind_of(c) == MessageKind::kImage || kind_of(c) == MessageKind::kCompressedImage;
}
bool is_pose(const Channel& c) {
  const MessageKind k = kind_of(c);
  return k == MessageKind::kOdometry || k == MessageKind::kPoseStamped || k == MessageKind::kTransformStamped;
}
// "/cam/image_raw/compressed" is in the namespace of "/cam/camera_info" ("/cam/").
bool in_namespace_of(const Channel& image, const Channel& camera_info) {
  const std::string& t = camera_info.topic;
  const std::string ns = t.substr(0, t.rfind('/') + 1);
  return !ns.empty() && image.topic.compare(0, ns.size(), ns) == 0;
}
bool named_label(const Channel& c) { return c.topic.find("label") != std::string::npos; }

ChannelList matching(const std::vector<Channel>& channels, const std::function<bool(const Channel&)>& fits) {
  ChannelList out;
  for (const Channel& c : channels)
    if (fits(c)) out.push_back(&c);
  return out;
}

std::string listed(const ChannelList& list) {
  std::vector<std::string> names;
  for (const Channel* c : list) names.push_back(fmt::format("{} ({})", c->topic, c->type));
  return names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "));
}

// The channel the user named with `option`, which must be one of `fitting` (its kind).
const Channel* named(const std::vector<Channel>& channels, const std::string& topic, const char* option,
                     const char* what, const ChannelList& fitting) {
  for (const Channel* c : fitting)
    if (c->topic == topic) return c;
  const bool exists = std::any_of(channels.begin(), channels.end(), [&](const Channel& c) { return c.topic == topic; });
  throw TopicChoiceError(fmt::format("{} {}: {}; the {} topics are: {}", option, topic,
                                     exists ? "its type is not " + std::string(what) : "no such topic in the recording",
                                     what, listed(fitting)));
}

[[noreturn]] void several(const char* what, const ChannelList& list, const char* option) {
  throw TopicChoiceError(fmt::format("the recording has {} {} topics: {}; choose one with {} (topic options: {})",
                                     list.size(), what, listed(list), option, kTopicOptions));
}

void choose_camera(const std::vector<Channel>& channels, const TopicChoice& choice, TopicSelection& s);
void choose_poses(const std::vector<Channel>& channels, const TopicChoice& choice, bool want_poses, TopicSelection& s);

}  // namespace

TopicSelection choose_topics(const std::vector<Channel>& channels, const TopicChoice& choice, bool want_poses,
                             bool want_camera, bool require_lidar) {
  TopicSelection s;
  // LiDAR.
  const ChannelList clouds = matching(channels, [](const Channel& c) { return kind_of(c) == MessageKind::kPointCloud2; });
  if (!choice.lidar.empty()) {
    s.lidar = named(channels, choice.lidar, "--lidar-topic", "sensor_msgs/PointCloud2", clouds);
    s.reasons.push_back(fmt::format("LiDAR: {} (--lidar-topic)", s.lidar->topic));
  } else if (clouds.size() == 1) {
    s.lidar = clouds[0];
    s.reasons.push_back(fmt::format("LiDAR: {} (the only PointCloud2 topic)", s.lidar->topic));
  } else if (clouds.size() > 1) {
    several("sensor_msgs/PointCloud2", clouds, "--lidar-topic");
  } else if (require_lidar) {
    throw Error(fmt::format("the recording has no sensor_msgs/PointCloud2 topic: nothing to map (its topics: {})",
                            listed(matching(channels, [](const Channel&) { return true; }))));
  }

  if (want_camera) choose_camera(channels, choice, s);
  choose_poses(channels, choice, want_poses, s);
  return s;
}

namespace {

void choose_camera(const std::vector<Channel>& channels, const TopicChoice& choice, TopicSelection& s) {
  // SIMULATED labels (before the camera: a label topic is no camera image).
  const ChannelList images = matching(channels, is_image);
  if (!choice.labels.empty()) {
    s.labels = named(channels, choice.labels, "--label-topic", "sensor_msgs/Image or CompressedImage", images);
    s.reasons.push_back(fmt::format("labels: {} (--label-topic)", s.labels->topic));
  } else {
    const ChannelList labels = matching(channels, [](const Channel& c) { return is_image(c) && named_label(c); });
    if (labels.size() > 1) several("label image", labels, "--label-topic");
    if (labels.size() == 1) {
      s.labels = labels[0];
      s.reasons.push_back(fmt::format("labels: {} (the only image topic named 'label'; SIMULATED labels)", s.labels->topic));
    }
  }

  // Camera: an image topic and its CameraInfo.
  const ChannelList infos = matching(channels, [](const Channel& c) { return kind_of(c) == MessageKind::kCameraInfo; });
  const auto info_for = [&](const Channel& image) {
    return matching(channels, [&](const Channel& c) { return kind_of(c) == MessageKind::kCameraInfo && in_namespace_of(image, c); });
  };
  if (!choice.image.empty()) {
    s.image = named(channels, choice.image, "--image-topic", "sensor_msgs/Image or CompressedImage", images);
    s.reasons.push_back(fmt::format("camera: {} (--image-topic)", s.image->topic));
  }
  if (!choice.camera_info.empty()) {
    s.camera_info = named(channels, choice.camera_info, "--camera-info-topic", "sensor_msgs/CameraInfo", infos);
    s.reasons.push_back(fmt::format("camera info: {} (--camera-info-topic)", s.camera_info->topic));
  }
  if (s.image && !s.camera_info) {
    const ChannelList own = info_for(*s.image);
    const ChannelList& pick = own.size() == 1 ? own : infos;
    if (pick.size() != 1)
      throw TopicChoiceError(fmt::format("--image-topic {}: {} CameraInfo topics could be its calibration: {}; choose "
                                         "one with --camera-info-topic",
                                         s.image->topic, pick.size(), listed(pick)));
    s.camera_info = pick[0];
    s.reasons.push_back(fmt::format("camera info: {} ({})", s.camera_info->topic,
                                    own.size() == 1 ? "in the camera's namespace" : "the only CameraInfo topic"));
  } else if (!s.image) {
    // Cameras: image topics (not the labels) with a CameraInfo in their namespace.
    ChannelList cameras;
    for (const Channel* image : images)
      if (image != s.labels && !info_for(*image).empty() &&
          (!s.camera_info || in_namespace_of(*image, *s.camera_info)))
        cameras.push_back(image);
    if (cameras.size() > 1) several("camera image (with a CameraInfo in their namespace)", cameras, "--image-topic");
    if (cameras.size() == 1) {
      s.image = cameras[0];
      if (!s.camera_info) s.camera_info = info_for(*s.image)[0];
      s.reasons.push_back(fmt::format("camera: {} with {} (the only image topic with a CameraInfo in its namespace)",
                                      s.image->topic, s.camera_info->topic));
    } else if (s.camera_info) {
      throw TopicChoiceError(fmt::format("--camera-info-topic {}: no image topic in its namespace; name it with "
                                         "--image-topic (image topics: {})",
                                         s.camera_info->topic, listed(images)));
    } else {
      s.reasons.push_back(fmt::format("camera: none (no image topic has a CameraInfo in its namespace; image topics: "
                                      "{}): geometry only",
                                      listed(images)));
    }
  }

}

void choose_poses(const std::vector<Channel>& channels, const TopicChoice& choice, bool want_poses, TopicSelection& s) {
  const ChannelList poses = matching(channels, is_pose);
  if (!choice.poses.empty()) {
    s.poses = named(channels, choice.poses, "--pose-topic",
                    "nav_msgs/Odometry, geometry_msgs/PoseStamped or geometry_msgs/TransformStamped", poses);
    s.reasons.push_back(fmt::format("poses: {} (--pose-topic)", s.poses->topic));
  } else if (want_poses && poses.size() == 1) {
    s.poses = poses[0];
    s.reasons.push_back(fmt::format("poses: {} (the only pose topic)", s.poses->topic));
  } else if (want_poses && poses.size() > 1) {
    several("pose", poses, "--pose-topic");
  }
}

}  // namespace

}  // namespace slamvdb
