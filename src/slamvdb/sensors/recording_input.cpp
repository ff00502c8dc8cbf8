#include "slamvdb/sensors/recording_input.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>
#include <deque>
#include <functional>
#include <map>
#include <set>

#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/recording/image.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/point_cloud2.hpp"
#include "slamvdb/sensors/recording_topics.hpp"
#include "slamvdb/sensors/tf_edges.hpp"

namespace slamvdb {

namespace {

namespace fs = std::filesystem;
using recording::Channel;
using recording::Message;
using recording::MessageKind;

// The topics the stream reads, by name (channel ids belong to one reader).
struct StreamTopics {
  std::string lidar, image, labels;
};

// Seconds as whole seconds plus the fraction, so that a stamp is the double a text file's decimal
// gives (the same scans stamped the same whether they come from a folder's times.txt or a recording).
double seconds_of(std::int64_t ns) {
  const std::int64_t whole = ns / 1'000'000'000, rest = ns % 1'000'000'000;
  return static_cast<double>(whole) + static_cast<double>(rest) / 1e9;
}

double stamp_of(const recording::Header& header, const Message& m, TimeSource source) {
  return seconds_of(source == TimeSource::kLog ? m.log_time_ns : header.stamp_ns);
}

std::string message_name(const Message& m) { return fmt::format("{} message {}", m.channel->topic, m.index); }

std::set<std::uint32_t> ids_of(const recording::RecordingReader& reader, const std::set<std::string>& topics) {
  std::set<std::uint32_t> ids;
  for (const Channel& c : reader.channels())
    if (topics.count(c.topic)) ids.insert(c.id);
  return ids;
}

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

// Reads the selected topics one message at a time. A camera image and a label image of the same
// stamp become one ImageRecord (as a folder pairs them by name).
class RecordingStream final : public SensorStream {
 public:
  RecordingStream(const fs::path& path, const StreamTopics& topics, const InputOptions& options, const CameraModel& camera,
                  bool with_images)
      : path_(path), reader_(recording::open_recording(path)), options_(options), camera_(camera) {
    lidar_ = ids_of(*reader_, {topics.lidar});
    if (with_images) {
      image_ = ids_of(*reader_, {topics.image});
      labels_ = ids_of(*reader_, {topics.labels});
      pair_ = !image_.empty() && !labels_.empty();
    }
    std::set<std::uint32_t> all = lidar_;
    all.insert(image_.begin(), image_.end());
    all.insert(labels_.begin(), labels_.end());
    reader_->select(all);
  }

  bool next(SensorFrame& out) override {
    while (ready_.empty()) {
      Message m;
      if (!reader_->next(m)) {
        flush_pending();
        if (ready_.empty()) return false;
        break;
      }
      ++messages_;
      try {
        take(m);
      } catch (const Error& e) {
        if (!options_.skip_bad_messages)
          throw Error(fmt::format("{}: {} ({}) does not decode: {} (--skip-bad-messages skips and counts such "
                                  "messages)",
                                  path_, message_name(m), m.channel->type, e.what()));
        ++skipped_[fmt::format("{} ({}): messages that do not decode", m.channel->topic, m.channel->type)];
      }
    }
    out = std::move(ready_.front());
    ready_.pop_front();
    return true;
  }

  StreamProgress progress() const override { return {reader_->bytes_read(), reader_->size_bytes(), messages_}; }

  std::vector<std::string> skipped() const override {
    std::vector<std::string> lines;
    for (const auto& [what, n] : skipped_) lines.push_back(fmt::format("{} {} skipped", what, n));
    return lines;
  }

 private:
  void take(const Message& m) {
    const MessageKind kind = recording::message_kind(m.channel->type);
    const auto serialization = m.channel->serialization;
    if (serialization == recording::Serialization::kOther || kind == MessageKind::kUnknown) {
      ++skipped_[fmt::format("{} ({}, {}): messages of a type slamvdb does not read", m.channel->topic, m.channel->type,
                             m.channel->encoding)];
      return;
    }
    if (lidar_.count(m.channel->id)) {
      const recording::PointCloud2View cloud = recording::decode_point_cloud2(m.data, serialization);
      SensorFrame frame;
      frame.kind = SensorFrame::Kind::kScan;
      frame.stamp = stamp_of(cloud.header, m, options_.time_source);
      frame.name = message_name(m);
      recording::extract_points(cloud, frame.points, &frame.point_times);
      // Times that are all the same (a driver writing 0, as our fixture writers do without times)
      // say nothing about the sweep: the scan is taken as one instant, as a file without times is.
      if (std::adjacent_find(frame.point_times.begin(), frame.point_times.end(), std::not_equal_to<>()) ==
          frame.point_times.end())
        frame.point_times.clear();
      // A scan after a pending image: the image first (time order); the same stamp: the scan first.
      if (pending_ && pending_->stamp < frame.stamp) flush_pending();
      ready_.push_back(std::move(frame));
      return;
    }
    const bool label = labels_.count(m.channel->id) > 0;
    auto bytes = std::make_shared<ImageBytes>();
    bytes->name = message_name(m);
    double stamp = 0;
    if (kind == MessageKind::kCompressedImage) {
      const recording::CompressedImageView image = recording::decode_compressed_image(m.data, serialization);
      stamp = stamp_of(image.header, m, options_.time_source);
      bytes->data.assign(image.data.begin(), image.data.end());  // decoded in the inference thread
    } else if (kind == MessageKind::kImage) {
      const recording::ImageView image = recording::decode_image(m.data, serialization);
      stamp = stamp_of(image.header, m, options_.time_source);
      if (static_cast<double>(image.width) * image.height > static_cast<double>(options_.read.max_image_pixels))
        throw Error(fmt::format("{} x {} pixels, more than the limit of {} (--max-image-pixels)", image.width,
                                image.height, options_.read.max_image_pixels));
      if (label) {
        recording::image_to_mono8(image, bytes->data);
        bytes->channels = 1;
      } else {
        recording::image_to_rgb8(image, bytes->data);
        bytes->channels = 3;
      }
      bytes->width = static_cast<int>(image.width);
      bytes->height = static_cast<int>(image.height);
    } else {
      ++skipped_[fmt::format("{} ({}): not an image type", m.channel->topic, m.channel->type)];
      return;
    }
    if (pending_ && (pending_->stamp != stamp || (label ? pending_->has_labels() : pending_->has_rgb())))
      flush_pending();
    if (!pending_) {
      pending_.emplace();
      pending_->stamp = stamp;
      pending_->width = camera_.width;
      pending_->height = camera_.height;
    }
    (label ? pending_->label_data : pending_->rgb_data) = std::move(bytes);
    if (!pair_ || (pending_->has_rgb() && pending_->has_labels())) flush_pending();
  }

  void flush_pending() {
    if (!pending_) return;
    SensorFrame frame;
    frame.kind = SensorFrame::Kind::kImage;
    frame.stamp = pending_->stamp;
    frame.name = pending_->rgb_data ? pending_->rgb_data->name : pending_->label_data->name;
    frame.image = std::move(*pending_);
    pending_.reset();
    ready_.push_back(std::move(frame));
  }

  fs::path path_;
  std::unique_ptr<recording::RecordingReader> reader_;
  InputOptions options_;
  CameraModel camera_;
  std::set<std::uint32_t> lidar_, image_, labels_;
  bool pair_ = false;
  std::optional<ImageRecord> pending_;
  std::deque<SensorFrame> ready_;
  std::uint64_t messages_ = 0;
  std::map<std::string, std::size_t> skipped_;
};

class RecordingInput final : public SensorInput {
 public:
  RecordingInput(const fs::path& path, const InputOptions& options) : path_(path), options_(options) {
    auto reader = recording::open_recording(path);
    kind_ = reader->describe();
    recording_ = true;
    sequence_.root = path;
    sequence_.layout = "recording";
    const TopicSelection topics = choose_topics(reader->channels(), options.topics, options.need_poses, !options.scans_only);
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
    // The small topics in one pass.
    std::set<std::string> small;
    if (want_images && topics.camera_info) small.insert(topics.camera_info->topic);
    if (topics.poses) small.insert(topics.poses->topic);
    for (const Channel& c : reader->channels())
      if (recording::message_kind(c.type) == MessageKind::kTf) small.insert(c.topic);
    TfEdges tf;
    std::optional<recording::CameraInfo> info;
    std::vector<double> pose_stamps;
    std::vector<Pose> poses;
    std::string pose_frame;
    if (!small.empty()) {
      reader->select(ids_of(*reader, small));
      Message m;
      while (reader->next(m)) {
        const MessageKind kind = recording::message_kind(m.channel->type);
        try {
          read_small(m, kind, topics, tf, info, pose_stamps, poses, pose_frame);
        } catch (const Error& e) {
          if (!options.skip_bad_messages)
            throw Error(fmt::format("{} ({}) does not decode: {}", message_name(m), m.channel->type, e.what()));
        }
      }
    }
    if (topics.poses) set_poses(topics.poses->topic, lidar_frame, pose_frame, tf, pose_stamps, poses);
    if (topics_.image.empty() && topics_.labels.empty()) {
      if (want_images) sequence_.notes.push_back("no camera in the recording: geometry only");
      return;
    }
    if (!info) {
      if (topics_.image.empty())  // labels alone: no calibration for them
        sequence_.notes.push_back("label images without a camera calibration are not used: geometry only");
      else
        throw Error(fmt::format("{}: no message on the camera info topic {}", path, topics.camera_info->topic));
      topics_.labels.clear();
      return;
    }
    sequence_.camera = camera_from_info(*info, fmt::format("{} (first message)", topics.camera_info->topic));
    apply_camera_options(sequence_, options.read);
    set_extrinsics(lidar_frame, info->header.frame_id, tf);
    has_camera_ = true;
    has_labels_ = !topics_.labels.empty();
  }

  std::unique_ptr<SensorStream> open(bool with_images) const override {
    return std::make_unique<RecordingStream>(path_, topics_, options_, sequence_.camera, with_images && has_camera_);
  }

 private:
  static std::string first_frame(const fs::path& path, const std::string& topic) {
    auto reader = recording::open_recording(path);
    reader->select(ids_of(*reader, {topic}));
    Message m;
    if (!reader->next(m)) throw Error(fmt::format("{}: no message on the LiDAR topic {}", path, topic));
    try {
      return recording::decode_point_cloud2(m.data, m.channel->serialization).header.frame_id;
    } catch (const Error& e) {
      throw Error(fmt::format("{} ({}) does not decode: {}", message_name(m), m.channel->type, e.what()));
    }
  }

  void read_small(const Message& m, MessageKind kind, const TopicSelection& topics, TfEdges& tf,
                  std::optional<recording::CameraInfo>& info, std::vector<double>& pose_stamps, std::vector<Pose>& poses,
                  std::string& pose_frame) {
    const auto ser = m.channel->serialization;
    if (kind == MessageKind::kTf) {
      for (const auto& t : recording::decode_tf_message(m.data, ser)) tf.add(t.header.frame_id, t.child_frame_id, t.T_parent_child);
    } else if (kind == MessageKind::kCameraInfo) {
      if (!info) info = recording::decode_camera_info(m.data, ser);
    } else if (topics.poses && m.channel->topic == topics.poses->topic) {
      double stamp = 0;
      if (kind == MessageKind::kOdometry) {
        const auto o = recording::decode_odometry(m.data, ser);
        stamp = stamp_of(o.header, m, options_.time_source);
        poses.push_back(o.T_frame_child);
        pose_frame = o.child_frame_id;
      } else if (kind == MessageKind::kPoseStamped) {
        const auto p = recording::decode_pose_stamped(m.data, ser);
        stamp = stamp_of(p.header, m, options_.time_source);
        poses.push_back(p.T_frame_pose);
      } else {
        const auto t = recording::decode_transform_stamped(m.data, ser);
        stamp = stamp_of(t.header, m, options_.time_source);
        poses.push_back(t.T_parent_child);
        pose_frame = t.child_frame_id;
      }
      pose_stamps.push_back(stamp);
    }
  }

  void set_poses(const std::string& topic, const std::string& lidar_frame, const std::string& pose_frame,
                 const TfEdges& tf, std::vector<double> stamps, std::vector<Pose> poses) {
    // Poses of another frame than the LiDAR's are moved to it through tf when they are connected.
    if (!pose_frame.empty() && pose_frame != lidar_frame) {
      if (const auto T_pose_lidar = tf.find(pose_frame, lidar_frame)) {
        for (Pose& T : poses) T = T * *T_pose_lidar;
        sequence_.notes.push_back(fmt::format("poses of {} are of frame {}: moved to the LiDAR frame {} through tf", topic,
                                              pose_frame, lidar_frame));
      } else {
        sequence_.notes.push_back(fmt::format("poses of {} are of frame {}, not the LiDAR's {}, and tf does not connect "
                                              "them: used as the LiDAR's", topic, pose_frame, lidar_frame));
      }
    }
    try {
      sequence_.poses = Trajectory(std::move(stamps), std::move(poses));
    } catch (const Error& e) {
      throw Error(fmt::format("poses on {}: {}", topic, e.what()));
    }
  }

  void set_extrinsics(const std::string& lidar_frame, const std::string& camera_frame, const TfEdges& tf) {
    const auto from_tf = tf.find(lidar_frame, camera_frame);
    if (!options_.extrinsics.empty()) {
      sequence_.T_lidar_camera = read_rellis_transforms(options_.extrinsics);
      sequence_.notes.push_back(fmt::format("T_lidar_camera from --extrinsics {}{}", options_.extrinsics,
                                            from_tf ? " (the recording's tf has one too: not used)" : ""));
    } else if (from_tf) {
      sequence_.T_lidar_camera = *from_tf;
      sequence_.notes.push_back(fmt::format("T_lidar_camera from tf ({} -> {})", lidar_frame, camera_frame));
    } else {
      throw Error(fmt::format("{}: no transform between the LiDAR frame '{}' and the camera frame '{}' in /tf_static or "
                              "/tf{}; give the extrinsics with --extrinsics FILE (RELLIS transforms.yaml form)",
                              path_, lidar_frame, camera_frame, tf.empty() ? " (the recording has no tf)" : ""));
    }
  }

  fs::path path_;
  InputOptions options_;
  StreamTopics topics_;
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
