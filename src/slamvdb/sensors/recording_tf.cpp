#include "slamvdb/sensors/recording_tf.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <functional>
#include <map>
#include <set>

#include "slamvdb/recording/messages.hpp"

namespace slamvdb {

namespace {

double seconds_of_ns(std::int64_t ns) {
  const std::int64_t whole = ns / 1'000'000'000, rest = ns % 1'000'000'000;
  return static_cast<double>(whole) + static_cast<double>(rest) / 1e9;
}

std::string frames_seen(const TfBuffer& tf) {
  const auto frames = tf.frames();
  return frames.empty() ? "none: the recording has no tf" : fmt::format("{}", fmt::join(frames, ", "));
}

}  // namespace

double message_seconds(const recording::Header& header, const recording::Message& m, TimeSource source) {
  return seconds_of_ns(source == TimeSource::kLog ? m.log_time_ns : header.stamp_ns);
}

bool is_static_tf_topic(const std::string& topic) { return topic.find("static") != std::string::npos; }

void add_tf_message(TfBuffer& tf, const recording::Message& m, TimeSource source) {
  const bool is_static = is_static_tf_topic(m.channel->topic);
  for (const auto& t : recording::decode_tf_message(m.data, m.channel->serialization)) {
    const double stamp = message_seconds(t.header, m, source);
    if (is_static) tf.add_static(t.header.frame_id, t.child_frame_id, stamp, t.T_parent_child);
    else tf.add(t.header.frame_id, t.child_frame_id, stamp, t.T_parent_child);
  }
}

PosesFromTf poses_from_tf(const TfBuffer& tf, const std::string& pose_frame, const std::string& sensor_frame,
                          const std::string& lidar_frame, const std::vector<double>& scan_stamps) {
  const auto known = tf.frames();
  for (const auto& [option, frame] : {std::pair{"--pose-frame", pose_frame}, std::pair{"--sensor-frame", sensor_frame}})
    if (!std::binary_search(known.begin(), known.end(), frame))
      throw TopicChoiceError(fmt::format("{} '{}': no such frame in the recording's tf (frames seen: {})", option, frame,
                                         frames_seen(tf)));
  const auto pose_sensor = tf.chain(pose_frame, sensor_frame);
  if (!pose_sensor)
    throw TopicChoiceError(fmt::format("--pose-frame '{}' and --sensor-frame '{}': tf does not connect them (frames "
                                       "seen: {})", pose_frame, sensor_frame, frames_seen(tf)));
  PosesFromTf out;
  out.notes.push_back(fmt::format("poses: tf {} -> {} at each scan's stamp (--pose-frame, --sensor-frame)", pose_frame,
                                  sensor_frame));
  std::optional<TfBuffer::Chain> sensor_lidar;
  if (sensor_frame != lidar_frame) {
    sensor_lidar = tf.chain(sensor_frame, lidar_frame);
    out.notes.push_back(sensor_lidar ? fmt::format("poses of {} moved to the LiDAR frame {} through tf", sensor_frame,
                                                   lidar_frame)
                                     : fmt::format("poses of {}, not the LiDAR's {}, and tf does not connect them: "
                                                   "used as the LiDAR's", sensor_frame, lidar_frame));
  }
  std::vector<double> stamps;
  std::vector<Pose> poses;
  std::size_t uncovered = 0;
  std::string first_problem;
  for (const double t : scan_stamps) {
    if (!stamps.empty() && t <= stamps.back()) continue;  // a stamp given twice: one pose
    try {
      Pose T = pose_sensor->at(t);
      if (sensor_lidar) T = T * sensor_lidar->at(t);
      stamps.push_back(t);
      poses.push_back(T);
    } catch (const TfLookupError& e) {
      if (uncovered++ == 0) first_problem = e.what();
    }
  }
  if (uncovered)
    out.notes.push_back(fmt::format("{} of {} scans have no pose from tf (first: {})", uncovered, scan_stamps.size(),
                                    first_problem));
  out.poses = Trajectory(std::move(stamps), std::move(poses));
  return out;
}

std::string tf_tree_text(const std::vector<TfEdgeSummary>& edges, const std::string& indent) {
  std::map<std::string, std::vector<const TfEdgeSummary*>> children;
  std::set<std::string> frames, with_parent;
  for (const TfEdgeSummary& e : edges) {
    children[e.parent].push_back(&e);
    frames.insert(e.parent), frames.insert(e.child);
    with_parent.insert(e.child);
  }
  std::string out;
  std::set<std::string> drawn;
  const std::function<void(const std::string&, std::size_t)> draw = [&](const std::string& frame, std::size_t depth) {
    if (!drawn.insert(frame).second) return;  // a cycle, or a second parent: drawn once
    const auto it = children.find(frame);
    if (it == children.end()) return;
    for (const TfEdgeSummary* e : it->second) {
      out += indent + std::string(2 * (depth + 1), ' ') + e->child + "  (";
      out += e->is_static ? fmt::format("static, {} transform{}", e->messages, e->messages == 1 ? "" : "s")
                          : fmt::format("dynamic: {} transforms, {:.1f} Hz", e->messages, e->rate_hz());
      out += ")\n";
      draw(e->child, depth + 1);
    }
  };
  for (const std::string& frame : frames)
    if (!with_parent.count(frame)) {
      out += indent + frame + "\n";
      draw(frame, 0);
    }
  for (const std::string& frame : frames)  // frames only in cycles
    if (!drawn.count(frame) && children.count(frame)) {
      out += indent + frame + "  (in a cycle)\n";
      draw(frame, 0);
    }
  return out;
}

}  // namespace slamvdb
