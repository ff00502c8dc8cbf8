#include "slamvdb/sensors/recording_input.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>
#include <set>

#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/point_cloud2.hpp"
#include "slamvdb/sensors/recording_stream.hpp"
#include "slamvdb/sensors/recording_tf.hpp"
#include "slamvdb/sensors/recording_topics.hpp"

namespace slamvdb {

namespace {

namespace fs = std::filesystem;
using recording::Channel;
using recording::Message;
using recording::MessageKind;

CameraModel camera_from_info(const recording::CameraInfo& info, const std::string& where) {
  const std::string& model = info.distortion_model;
  const bool no_distortion = std::all_of(info.D.begin(), info.D.end(), [](double d) { return d == 0.0; });
  if (!(model == "plumb_bob" || ((model.empty() || model == "none") && no_distortion)))
    throw Error(fmt::format("{}: distortion model '{}' is not supported (slamvdb reads plumb_bob, or none)", where, model));
  if (info.D.size() > 5)
    throw Error(fmt::format("{}: plumb_bob with {} coefficients; expected at most 5 (k1 k2 p1 p2 k3)", where, info.D.size()));
  CameraModel camera;
  camera.width = static_cast<int>(info.width);
  camera.height = static_cast<int>(info.height);
  camera.fx = info.K[0];
  camera.fy = info.K[4];
  camera.cx = info.K[2];
  camera.cy = info.K[5];
  std::copy(info.D.begin(), info.D.end(), camera.distortion.begin());
  return camera;
}

class RecordingInput final : public SensorInput {
 public:
  RecordingInput(const fs::path& path, const InputOptions& options) : path_(path), options_(options) {
    auto reader = recording::open_recording(path);
    kind_ = reader->describe();
    recording_ = true;
    sequence_.root = path;
    sequence_.layout = "recording";
    const bool poses_from_tf = !options.pose_frame.empty();
    const TopicSelection topics =
        choose_topics(reader->channels(), options.topics, options.need_poses && !poses_from_tf, !options.scans_only);
    for (const auto& line : topics.reasons) sequence_.notes.push_back(line);
    topics_.lidar = topics.lidar->topic;
    scan_count_ = topics.lidar->message_count.value_or(0);
    const bool want_images = !options.scans_only;
    if (want_images && topics.image) topics_.image = topics.image->topic;
    if (want_images && topics.labels) topics_.labels = topics.labels->topic;
    sequence_.notes.push_back(options.time_source == TimeSource::kHeader
                                  ? "time source: header stamps (--time-source log for record times)"
                                  : "time source: log (record) times (--time-source log)");
    for (const auto& note : reader->notes()) sequence_.notes.push_back(note);

    // The LiDAR's frame, from its first message.
    const std::string lidar_frame = first_frame(path, topics_.lidar);
    // The small topics in one pass (and the scans' stamps when tf gives the poses).
    std::set<std::string> small;
    if (want_images && topics.camera_info) small.insert(topics.camera_info->topic);
    if (topics.poses) small.insert(topics.poses->topic);
    if (poses_from_tf) small.insert(topics_.lidar);
    for (const Channel& c : reader->channels())
      if (recording::message_kind(c.type) == MessageKind::kTf) small.insert(c.topic);
    auto tf = std::make_shared<TfBuffer>();
    SmallTopics read;
    if (!small.empty()) {
      reader->select(recording_channel_ids(*reader, small));
      Message m;
      while (reader->next(m)) {
        const MessageKind kind = recording::message_kind(m.channel->type);
        try {
          read_small(m, kind, topics, *tf, read);
        } catch (const Error& e) {
          if (!options.skip_bad_messages)
            throw Error(
                fmt::format("{} ({}) does not decode: {}", recording_message_name(m), m.channel->type, e.what()));
        }
      }
    }
    tf_ = tf;
    if (!tf_->empty()) {
      const auto edges = tf_->edges();
      const auto dynamic = std::count_if(edges.begin(), edges.end(), [](const TfEdgeSummary& e) { return !e.is_static; });
      sequence_.notes.push_back(fmt::format("tf: {} frames, {} edges ({} moving, {} stamps kept)", tf_->frames().size(),
                                            edges.size(), dynamic, tf_->stored_stamps()));
    }
    if (poses_from_tf) {
      PosesFromTf from_tf = slamvdb::poses_from_tf(
          *tf_, options.pose_frame, options.sensor_frame.empty() ? lidar_frame : options.sensor_frame, lidar_frame,
          read.scan_stamps);
      for (auto& note : from_tf.notes) sequence_.notes.push_back(std::move(note));
      sequence_.poses = std::move(from_tf.poses);
    } else if (topics.poses) {
      set_poses(topics.poses->topic, lidar_frame, read);
    }
    if (topics_.image.empty() && topics_.labels.empty()) {
      if (want_images) sequence_.notes.push_back("no camera in the recording: geometry only");
      return;
    }
    if (!read.info) {
      if (topics_.image.empty())  // labels alone: no calibration for them
        sequence_.notes.push_back("label images without a camera calibration are not used: geometry only");
      else
        throw Error(fmt::format("{}: no message on the camera info topic {}", path, topics.camera_info->topic));
      topics_.labels.clear();
      return;
    }
    sequence_.camera = camera_from_info(*read.info, fmt::format("{} (first message)", topics.camera_info->topic));
    apply_camera_options(sequence_, options.read);
    set_extrinsics(lidar_frame, read.info->header.frame_id, read.info_stamp);
    has_camera_ = true;
    has_labels_ = !topics_.labels.empty();
  }

  std::unique_ptr<SensorStream> open(bool with_images) const override {
    return open_recording_stream(path_, topics_, options_, sequence_.camera, with_images && has_camera_, tf_,
                                 lidar_camera_);
  }

 private:
  // What the pass over the small topics gathers.
  struct SmallTopics {
    std::optional<recording::CameraInfo> info;
    double info_stamp = 0;
    std::vector<double> pose_stamps, scan_stamps;
    std::vector<Pose> poses;
    std::string pose_frame;
  };

  static std::string first_frame(const fs::path& path, const std::string& topic) {
    auto reader = recording::open_recording(path);
    reader->select(recording_channel_ids(*reader, {topic}));
    Message m;
    if (!reader->next(m)) throw Error(fmt::format("{}: no message on the LiDAR topic {}", path, topic));
    try {
      return recording::decode_point_cloud2(m.data, m.channel->serialization).header.frame_id;
    } catch (const Error& e) {
      throw Error(fmt::format("{} ({}) does not decode: {}", recording_message_name(m), m.channel->type, e.what()));
    }
  }

  void read_small(const Message& m, MessageKind kind, const TopicSelection& topics, TfBuffer& tf, SmallTopics& read) {
    const auto ser = m.channel->serialization;
    const TimeSource source = options_.time_source;
    if (kind == MessageKind::kTf) {
      add_tf_message(tf, m, source);
    } else if (m.channel->topic == topics_.lidar) {
      read.scan_stamps.push_back(message_seconds(recording::decode_point_cloud2(m.data, ser).header, m, source));
    } else if (kind == MessageKind::kCameraInfo) {
      if (!read.info) {
        read.info = recording::decode_camera_info(m.data, ser);
        read.info_stamp = message_seconds(read.info->header, m, source);
      }
    } else if (topics.poses && m.channel->topic == topics.poses->topic) {
      double stamp = 0;
      if (kind == MessageKind::kOdometry) {
        const auto o = recording::decode_odometry(m.data, ser);
        stamp = message_seconds(o.header, m, source);
        read.poses.push_back(o.T_frame_child);
        read.pose_frame = o.child_frame_id;
      } else if (kind == MessageKind::kPoseStamped) {
        const auto p = recording::decode_pose_stamped(m.data, ser);
        stamp = message_seconds(p.header, m, source);
        read.poses.push_back(p.T_frame_pose);
      } else {
        const auto t = recording::decode_transform_stamped(m.data, ser);
        stamp = message_seconds(t.header, m, source);
        read.poses.push_back(t.T_parent_child);
        read.pose_frame = t.child_frame_id;
      }
      read.pose_stamps.push_back(stamp);
    }
  }

  void set_poses(const std::string& topic, const std::string& lidar_frame, SmallTopics& read) {
    // Poses of another frame than the LiDAR's are moved to it through tf (at each pose's stamp)
    // when tf connects them.
    const std::string& pose_frame = read.pose_frame;
    if (!pose_frame.empty() && pose_frame != lidar_frame) {
      if (const auto pose_lidar = tf_->chain(pose_frame, lidar_frame)) {
        try {
          for (std::size_t i = 0; i < read.poses.size(); ++i) read.poses[i] = read.poses[i] * pose_lidar->at(read.pose_stamps[i]);
        } catch (const TfLookupError& e) {
          throw Error(fmt::format("poses on {}: moving them from {} to the LiDAR frame {}: {}", topic, pose_frame,
                                  lidar_frame, e.what()));
        }
        sequence_.notes.push_back(fmt::format("poses of {} are of frame {}: moved to the LiDAR frame {} through tf", topic,
                                              pose_frame, lidar_frame));
      } else {
        sequence_.notes.push_back(fmt::format("poses of {} are of frame {}, not the LiDAR's {}, and tf does not connect "
                                              "them: used as the LiDAR's", topic, pose_frame, lidar_frame));
      }
    }
    try {
      sequence_.poses = Trajectory(std::move(read.pose_stamps), std::move(read.poses));
    } catch (const Error& e) {
      throw Error(fmt::format("poses on {}: {}", topic, e.what()));
    }
  }

  void set_extrinsics(const std::string& lidar_frame, const std::string& camera_frame, double first_info_stamp) {
    auto from_tf = tf_->chain(lidar_frame, camera_frame);
    if (!options_.extrinsics.empty()) {
      sequence_.T_lidar_camera = read_rellis_transforms(options_.extrinsics);
      sequence_.notes.push_back(fmt::format("T_lidar_camera from --extrinsics {}{}", options_.extrinsics,
                                            from_tf ? " (the recording's tf has one too: not used)" : ""));
    } else if (from_tf && from_tf->is_static()) {
      sequence_.T_lidar_camera = from_tf->at(0.0);
      sequence_.notes.push_back(fmt::format("T_lidar_camera from tf ({} -> {})", lidar_frame, camera_frame));
    } else if (from_tf) {
      // Moving extrinsics: each image gets the transform at its stamp (RecordingStream); the
      // sequence's is the one at the first camera info, for what reads only that.
      try {
        sequence_.T_lidar_camera = from_tf->at(first_info_stamp);
      } catch (const TfLookupError&) {
        // tf does not cover the first camera info: the images carry their own (or are skipped and counted)
      }
      lidar_camera_ = std::move(from_tf);
      sequence_.notes.push_back(fmt::format("T_lidar_camera from tf ({} -> {}), moving: looked up at each image's "
                                            "stamp", lidar_frame, camera_frame));
    } else {
      throw Error(fmt::format("{}: no transform between the LiDAR frame '{}' and the camera frame '{}' in /tf_static or "
                              "/tf{}; give the extrinsics with --extrinsics FILE (RELLIS transforms.yaml form)",
                              path_, lidar_frame, camera_frame, tf_->empty() ? " (the recording has no tf)" : ""));
    }
  }

  fs::path path_;
  InputOptions options_;
  StreamTopics topics_;
  std::shared_ptr<const TfBuffer> tf_;
  std::optional<TfBuffer::Chain> lidar_camera_;  // when the LiDAR-camera chain moves
};

}  // namespace

std::unique_ptr<SensorInput> open_recording_input(const fs::path& path, const InputOptions& options) {
  try {
    return std::make_unique<RecordingInput>(path, options);
  } catch (const TopicChoiceError&) {
    throw;  // the command names the input
  } catch (const Error& e) {
    if (std::string_view(e.what()).find(path.filename().string()) != std::string_view::npos) throw;
    throw Error(fmt::format("{}: {}", path, e.what()));  // every message names the recording
  }
}

}  // namespace slamvdb
