#include "slamvdb/sensors/input_summary.hpp"

#include <fmt/format.h>

#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/recording.hpp"
#include "slamvdb/sensors/recording_tf.hpp"
#include "slamvdb/sensors/recording_topics.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

double TopicSummary::rate_hz() const {
  return messages > 1 && last_ns > first_ns ? static_cast<double>(messages - 1) / (static_cast<double>(last_ns - first_ns) * 1e-9)
                                            : 0.0;
}

namespace {

InputSummary summarize_recording(const std::filesystem::path& path) {
  InputSummary s;
  s.path = path.string();
  s.recording = true;
  auto reader = recording::open_recording(path);
  s.kind = reader->describe();
  s.bytes = reader->size_bytes();
  std::map<std::uint32_t, TopicSummary> topics;
  for (const recording::Channel& c : reader->channels()) topics[c.id] = {c.topic, c.type, c.encoding};
  TfBuffer tf(kDefaultTfTolerance, false);  // counts and spans only: /tf can be large
  recording::Message m;
  bool first = true;
  while (reader->next(m)) {
    TopicSummary& t = topics[m.channel->id];
    if (t.messages++ == 0) t.first_ns = m.log_time_ns;
    t.last_ns = m.log_time_ns;
    t.bytes += m.data.size();
    if (first) s.start_ns = m.log_time_ns, first = false;
    s.end_ns = m.log_time_ns;
    ++s.messages;
    if (recording::message_kind(m.channel->type) == recording::MessageKind::kTf &&
        m.channel->serialization != recording::Serialization::kOther) {
      try {
        add_tf_message(tf, m, TimeSource::kHeader);
      } catch (const Error& e) {
        s.notes.push_back(fmt::format("{} message {} does not decode: {}", m.channel->topic, m.index, e.what()));
      }
    }
  }
  for (auto& [id, t] : topics) s.topics.push_back(std::move(t));
  s.tf_edges = tf.edges();
  try {
    const TopicSelection chosen = choose_topics(reader->channels(), {}, true, true, false);
    s.choices = chosen.reasons;
    if (!chosen.lidar) s.choices.insert(s.choices.begin(), "LiDAR: none (no sensor_msgs/PointCloud2 topic)");
  } catch (const TopicChoiceError& e) {
    s.choices.push_back(fmt::format("a choice is needed: {}", e.what()));
  }
  for (const auto& note : reader->notes()) s.notes.push_back(note);
  return s;
}

InputSummary summarize_folder(const std::filesystem::path& path) {
  InputOptions options;
  options.scans_only = true;  // a plain folder of scans is an input too (odometry)
  InputSummary s;
  s.path = path.string();
  std::unique_ptr<SensorInput> input;
  try {
    InputOptions full;
    input = open_sensor_input(path, full);
  } catch (const Error&) {
    input = open_sensor_input(path, options);
  }
  const Sequence& seq = input->sequence();
  s.kind = input->kind();
  std::size_t labelled = 0, with_rgb = 0;
  for (const ImageRecord& image : seq.images) labelled += image.has_labels(), with_rgb += image.has_rgb();
  s.facts.push_back(fmt::format("scans: {}{}", seq.scans.size(),
                                seq.scans.empty() ? ""
                                                  : fmt::format(" from {:.3f} s to {:.3f} s", seq.scans.front().stamp,
                                                                seq.scans.back().stamp)));
  s.facts.push_back(fmt::format("images: {} ({} camera images, {} SIMULATED-style label images)", seq.images.size(),
                                with_rgb, labelled));
  s.facts.push_back(fmt::format("poses: {}", seq.poses.empty() ? std::string("none (map needs --poses or --odometry)")
                                                               : fmt::format("{} (ground truth)", seq.poses.size())));
  if (!seq.images.empty())
    s.facts.push_back(fmt::format("camera: {} x {}, fx {:.1f} fy {:.1f} cx {:.1f} cy {:.1f}", seq.camera.width,
                                  seq.camera.height, seq.camera.fx, seq.camera.fy, seq.camera.cx, seq.camera.cy));
  s.notes = seq.notes;
  return s;
}

}  // namespace

InputSummary summarize_input(const std::filesystem::path& path) {
  return recording::is_recording(path) ? summarize_recording(path) : summarize_folder(path);
}

std::string summary_text(const InputSummary& s) {
  std::string out = fmt::format("{}: {}\n", s.path, s.kind);
  if (s.recording) {
    const double seconds = static_cast<double>(s.end_ns - s.start_ns) * 1e-9;
    out += fmt::format("  duration {:.3f} s, from {:.9f} to {:.9f} (log times, s since the epoch); {} messages, "
                       "{:.1f} MB of files\n",
                       seconds, static_cast<double>(s.start_ns) * 1e-9, static_cast<double>(s.end_ns) * 1e-9,
                       s.messages, static_cast<double>(s.bytes) / 1e6);
    out += "  topics:\n";
    for (const TopicSummary& t : s.topics)
      out += fmt::format("    {}  {} ({})  {} messages, {:.2f} Hz, {:.2f} MB\n", t.topic, t.type, t.encoding,
                         t.messages, t.rate_hz(), static_cast<double>(t.bytes) / 1e6);
    out += "  tf frames (each child under its parent):\n";
    out += s.tf_edges.empty() ? "    none\n" : tf_tree_text(s.tf_edges, "    ");
    out += "  slamvdb would use:\n";
    for (const auto& choice : s.choices) out += "    " + choice + "\n";
  }
  for (const auto& fact : s.facts) out += "  " + fact + "\n";
  for (const auto& note : s.notes) out += "  note: " + note + "\n";
  return out;
}

std::string summary_json(const InputSummary& s) {
  nlohmann::json j = {{"path", s.path}, {"kind", s.kind}, {"recording", s.recording}};
  if (s.recording) {
    j["start_ns"] = s.start_ns;
    j["end_ns"] = s.end_ns;
    j["duration_s"] = static_cast<double>(s.end_ns - s.start_ns) * 1e-9;
    j["messages"] = s.messages;
    j["bytes"] = s.bytes;
    nlohmann::json topics = nlohmann::json::array();
    for (const TopicSummary& t : s.topics)
      topics.push_back({{"topic", t.topic}, {"type", t.type}, {"encoding", t.encoding}, {"messages", t.messages},
                        {"bytes", t.bytes}, {"rate_hz", t.rate_hz()}});
    j["topics"] = topics;
    nlohmann::json tf = nlohmann::json::array();
    for (const TfEdgeSummary& e : s.tf_edges)
      tf.push_back({{"parent", e.parent}, {"child", e.child}, {"static", e.is_static}, {"transforms", e.messages},
                    {"first_stamp", e.first}, {"last_stamp", e.last}, {"rate_hz", e.rate_hz()}});
    j["tf"] = tf;
    j["uses"] = s.choices;
  } else {
    j["holds"] = s.facts;
  }
  j["notes"] = s.notes;
  return j.dump(2) + "\n";
}

}  // namespace slamvdb
