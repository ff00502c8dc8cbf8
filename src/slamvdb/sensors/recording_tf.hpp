#pragma once
// What a recording's tf gives the commands: the buffer filled from /tf and /tf_static messages,
// the poses of a sensor frame in a pose frame at each scan's stamp (--pose-frame, --sensor-frame),
// and the tree as `inspect` draws it.
#include <string>
#include <vector>

#include "slamvdb/fusion/trajectory.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/recording.hpp"
#include "slamvdb/sensors/sensor_input.hpp"
#include "slamvdb/sensors/tf_buffer.hpp"

namespace slamvdb {

// A message's time in seconds: its header stamp, or its log (record) time with TimeSource::kLog.
// Whole seconds plus the fraction, so that a stamp is the double a text file's decimal gives.
double message_seconds(const recording::Header& header, const recording::Message& m, TimeSource source);

// Whether a tf topic carries static transforms (/tf_static, or any topic named so).
bool is_static_tf_topic(const std::string& topic);

// Adds every transform of a tf2_msgs/TFMessage or tf/tfMessage. Throws Error when it does not decode.
void add_tf_message(TfBuffer& tf, const recording::Message& m, TimeSource source);

struct PosesFromTf {
  Trajectory poses;                // T_pose_lidar at the scan stamps tf covers
  std::vector<std::string> notes;  // where they came from, and the scans tf does not cover
};
// T_pose_sensor at each scan stamp, moved to the LiDAR's frame through tf when the sensor frame is
// another. Frames tf does not know, or does not connect, are a TopicChoiceError (a usage error)
// listing the frames seen. Scans outside the range of a dynamic edge get no pose (counted in the
// notes; the mapper counts them as outside the pose range).
PosesFromTf poses_from_tf(const TfBuffer& tf, const std::string& pose_frame, const std::string& sensor_frame,
                          const std::string& lidar_frame, const std::vector<double>& scan_stamps);

// The tree, one frame a line, each child indented under its parent with its edge's kind, count and
// rate ("os1_sensor  (dynamic: 64 transforms, 10.0 Hz)"); roots (frames without a parent) first.
std::string tf_tree_text(const std::vector<TfEdgeSummary>& edges, const std::string& indent);

}  // namespace slamvdb
