#pragma once
// What an input holds, for `slamvdb inspect`: a recording's containers, time span, topics (type,
// count, rate, bytes), tf frames and the topics slamvdb would use (and why); a dataset folder's
// layout, scans, images, poses and camera. Read in one pass with memory bounded by a message.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "slamvdb/sensors/tf_buffer.hpp"

namespace slamvdb {

struct TopicSummary {
  std::string topic, type, encoding;
  std::uint64_t messages = 0, bytes = 0;
  std::int64_t first_ns = 0, last_ns = 0;  // log times
  double rate_hz() const;  // messages per second over its span (0 with fewer than two)
};

struct InputSummary {
  std::string path, kind;  // kind: the container's description, or "rellis3d" / "kitti" folder
  bool recording = false;
  std::int64_t start_ns = 0, end_ns = 0;  // log times (recordings)
  std::uint64_t bytes = 0, messages = 0;
  std::vector<TopicSummary> topics;
  std::vector<TfEdgeSummary> tf_edges;  // by parent, then child
  std::vector<std::string> choices;   // which topic slamvdb would use for what, and why (or what it needs)
  std::vector<std::string> facts;     // dataset folders: what they hold, one line each
  std::vector<std::string> notes;
};

// Throws Error naming the path when it is neither a recording nor a dataset folder.
InputSummary summarize_input(const std::filesystem::path& path);
std::string summary_text(const InputSummary& summary);
std::string summary_json(const InputSummary& summary);

}  // namespace slamvdb
