#include "slamvdb/sensors/recording_stream.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>
#include <deque>
#include <functional>
#include <map>

#include "slamvdb/recording/image.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/point_cloud2.hpp"
#include "slamvdb/sensors/recording_tf.hpp"

namespace slamvdb {

std::string recording_message_name(const recording::Message& m) {
  return fmt::format("{} message {}", m.channel->topic, m.index);
}

std::set<std::uint32_t> recording_channel_ids(const recording::RecordingReader& reader, const std::set<std::string>& topics) {
  std::set<std::uint32_t> ids;
  for (const recording::Channel& c : reader.channels())
    if (topics.count(c.topic)) ids.insert(c.id);
  return ids;
}

namespace {

namespace fs = std::filesystem;
using recording::Message;
using recording::MessageKind;

// Reads the selected topics one message at a time. A camera image and a label image of the same
// stamp become one ImageRecord (as a folder pairs them by name).
class RecordingStream final : public SensorStream {
 public:
  RecordingStream(const fs::path& path, const StreamTopics& topics, const InputOptions& options, const CameraModel& camera,
                  bool with_images, std::shared_ptr<const TfBuffer> tf, std::optional<TfBuffer::Chain> lidar_camera)
      : path_(path), reader_(recording::open_recording(path)), options_(options), camera_(camera), tf_(std::move(tf)),
        lidar_camera_(std::move(lidar_camera)) {
    lidar_ = recording_channel_ids(*reader_, {topics.lidar});
    if (with_images) {
      image_ = recording_channel_ids(*reader_, {topics.image});
      labels_ = recording_channel_ids(*reader_, {topics.labels});
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
                                  path_, recording_message_name(m), m.channel->type, e.what()));
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
    if (!first_tf_problem_.empty()) lines.push_back("first image outside tf's range: " + first_tf_problem_);
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
      frame.stamp = message_seconds(cloud.header, m, options_.time_source);
      frame.name = recording_message_name(m);
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
    bytes->name = recording_message_name(m);
    double stamp = 0;
    if (kind == MessageKind::kCompressedImage) {
      const recording::CompressedImageView image = recording::decode_compressed_image(m.data, serialization);
      stamp = message_seconds(image.header, m, options_.time_source);
      bytes->data.assign(image.data.begin(), image.data.end());  // decoded in the inference thread
    } else if (kind == MessageKind::kImage) {
      const recording::ImageView image = recording::decode_image(m.data, serialization);
      stamp = message_seconds(image.header, m, options_.time_source);
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
    if (lidar_camera_) {
      try {
        frame.image.T_lidar_camera = lidar_camera_->at(frame.stamp);
      } catch (const TfLookupError& e) {
        ++skipped_["images outside the time range of the LiDAR-camera transform in tf"];
        if (first_tf_problem_.empty()) first_tf_problem_ = fmt::format("{}: {}", frame.name, e.what());
        return;
      }
    }
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
  std::shared_ptr<const TfBuffer> tf_;
  std::optional<TfBuffer::Chain> lidar_camera_;
  std::string first_tf_problem_;
};

}  // namespace

std::unique_ptr<SensorStream> open_recording_stream(const fs::path& path, const StreamTopics& topics,
                                                    const InputOptions& options, const CameraModel& camera,
                                                    bool with_images, std::shared_ptr<const TfBuffer> tf,
                                                    std::optional<TfBuffer::Chain> lidar_camera) {
  return std::make_unique<RecordingStream>(path, topics, options, camera, with_images, std::move(tf),
                                           std::move(lidar_camera));
}

}  // namespace slamvdb
