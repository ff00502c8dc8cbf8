#pragma once
// For tests only: recordings made by writers that are not slamvdb's (tests/recording_fixtures/,
// npm packages and Python's sqlite3; see its README), run at test time on a small SIMULATED
// sequence, and the manifests those writers keep of what they wrote (topic, type, log time, size
// and CRC-32 of each message's bytes), to compare with what a reader delivers.
#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::testing {

inline std::filesystem::path recording_fixtures_dir() {
  return std::filesystem::path(SLAMVDB_SOURCE_DIR) / "tests" / "recording_fixtures";
}

// The small SIMULATED drive the fixture writers record (1.5 m: 4 scans of 64 x 256 points, 2
// camera images of 160 x 100).
inline synth::SynthConfig recording_sequence_config() {
  synth::SynthConfig config;
  config.length_m = 1.5;
  config.image_width = 160;
  config.image_height = 100;
  config.lidar.columns = 256;
  return config;
}

// A SIMULATED drive in the RELLIS-3D layout, written into `dir`.
inline void write_recording_sequence(const std::filesystem::path& dir,
                                     const synth::SynthConfig& config = recording_sequence_config()) {
  synth::write_synthetic_sequence(config, dir, true);
}

// Runs tests/recording_fixtures/<script> <args> (args already shell-quoted): a .py with Debian's
// python3, a .mjs with node. The test fails with the writer's output when it does not exit 0.
inline bool run_fixture_writer(const std::string& script, const std::string& args) {
  const bool python = std::filesystem::path(script).extension() == ".py";
  const CommandResult r = run_command(std::string("exec ") + (python ? "/usr/bin/python3 " : "node ") +
                                          quote_path(recording_fixtures_dir() / script) + " " + args + " 2>&1",
                                      300.0);
  if (!r.exited() || r.exit_code != 0) {
    ADD_FAILURE() << script << " " << args << " failed (exit " << r.exit_code << ", signal " << r.signal
                  << (python ? "; is python3-rosbag installed?"
                             : "; are node and tests/recording_fixtures/node_modules installed?")
                  << " scripts/setup.sh does it):\n"
                  << r.output;
    return false;
  }
  return true;
}

struct WrittenMessage {
  std::string topic, type;
  std::int64_t log_time_ns = 0;
  std::uint64_t size = 0;
  std::uint32_t crc32 = 0;
  bool in_finished_chunk = true;  // write_ros1_bag.py --kill-after: false past the last finished chunk
  bool operator==(const WrittenMessage&) const = default;
};

// The writer's manifest, in writing order (the log time is a string in the Node writers'
// manifests, for BigInt, and a number in write_ros1_bag.py's).
inline std::vector<WrittenMessage> read_manifest(const std::filesystem::path& file) {
  std::vector<WrittenMessage> out;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const auto j = nlohmann::json::parse(line);
    const auto& log_time = j.at("log_time_ns");
    out.push_back({j.at("topic").get<std::string>(), j.at("type").get<std::string>(),
                   log_time.is_string() ? std::stoll(log_time.get<std::string>()) : log_time.get<std::int64_t>(),
                   j.at("size").get<std::uint64_t>(), j.at("crc32").get<std::uint32_t>(),
                   j.value("in_finished_chunk", true)});
  }
  return out;
}

// The order a reader must deliver them in: by log time, equal times in writing order.
inline std::vector<WrittenMessage> in_log_time_order(std::vector<WrittenMessage> written) {
  std::stable_sort(written.begin(), written.end(),
                   [](const WrittenMessage& a, const WrittenMessage& b) { return a.log_time_ns < b.log_time_ns; });
  return written;
}

struct ReadMessage {
  std::string topic, type;
  recording::Serialization serialization = recording::Serialization::kRos1;
  std::int64_t log_time_ns = 0;
  std::uint64_t size = 0;
  std::uint32_t crc32 = 0;
  std::uint64_t index = 0;
};

// Every message a reader delivers (until next() returns false).
inline std::vector<ReadMessage> read_all(recording::RecordingReader& reader) {
  std::vector<ReadMessage> out;
  recording::Message m;
  while (reader.next(m)) {
    out.push_back({m.channel->topic, m.channel->type, m.channel->serialization, m.log_time_ns, m.data.size(),
                   static_cast<std::uint32_t>(crc32_z(0, m.data.data(), m.data.size())), m.index});
  }
  return out;
}

// Whether `read` is `expected` message for message (topic, type, log time, size, CRC of the bytes),
// with Message::index counting from 0; says where they first differ.
inline ::testing::AssertionResult same_messages(const std::vector<WrittenMessage>& expected,
                                                const std::vector<ReadMessage>& read) {
  for (std::size_t i = 0; i < std::min(expected.size(), read.size()); ++i) {
    const WrittenMessage& e = expected[i];
    const ReadMessage& r = read[i];
    if (e.topic != r.topic || e.type != r.type || e.log_time_ns != r.log_time_ns || e.size != r.size ||
        e.crc32 != r.crc32 || r.index != i)
      return ::testing::AssertionFailure()
             << "message " << i << " differs: written " << e.topic << " " << e.type << " t=" << e.log_time_ns
             << " size " << e.size << " crc " << e.crc32 << ", read " << r.topic << " " << r.type
             << " t=" << r.log_time_ns << " size " << r.size << " crc " << r.crc32 << " index " << r.index;
  }
  if (expected.size() != read.size())
    return ::testing::AssertionFailure() << expected.size() << " messages written, " << read.size() << " read";
  return ::testing::AssertionSuccess();
}

// Checks a reader's channels against the manifest (one per topic: its type, `serialization` and
// the encoding that names it, its message count) and its time range against the first and last
// log times written.
inline void expect_channels_of(const recording::RecordingReader& reader, const std::vector<WrittenMessage>& written,
                               recording::Serialization serialization) {
  std::map<std::string, std::uint64_t> count;
  for (const auto& w : written) ++count[w.topic];
  ASSERT_EQ(reader.channels().size(), count.size());
  for (const recording::Channel& c : reader.channels()) {
    SCOPED_TRACE(c.topic);
    const auto it = std::find_if(written.begin(), written.end(), [&](const auto& w) { return w.topic == c.topic; });
    ASSERT_NE(it, written.end());
    EXPECT_EQ(c.type, it->type);  // in ROS 1 form ("sensor_msgs/msg/PointCloud2" in a ROS 2 bag)
    EXPECT_EQ(c.serialization, serialization);
    EXPECT_EQ(c.encoding, serialization == recording::Serialization::kCdr ? "cdr" : "ros1");
    ASSERT_TRUE(c.message_count.has_value());  // from a summary or index, or counted
    EXPECT_EQ(*c.message_count, count[c.topic]);
  }
  const auto [first, last] = std::minmax_element(
      written.begin(), written.end(), [](const auto& a, const auto& b) { return a.log_time_ns < b.log_time_ns; });
  ASSERT_TRUE(reader.time_range().has_value());
  EXPECT_EQ(reader.time_range()->start_ns, first->log_time_ns);
  EXPECT_EQ(reader.time_range()->end_ns, last->log_time_ns);
}

// A reader's notes, one per line.
inline std::string notes_text(const recording::RecordingReader& reader) {
  std::string s;
  for (const auto& n : reader.notes()) s += n + "\n";
  return s;
}

// A test suite's fixture: the SIMULATED sequence written once per suite in a temporary folder, and
// the fixture writers run on it.
class RecordingFixtureTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir() = std::filesystem::temp_directory_path() / ("slamvdb-recording-test-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir());
    write_recording_sequence(dir() / "seq");
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir()); }
  static std::filesystem::path& dir() {
    static std::filesystem::path d;
    return d;
  }
  // `script` (write_mcap.mjs, write_rosbag2.mjs) writes dir()/`name` from the sequence with
  // `options`, and its manifest beside it (manifest_of).
  static std::filesystem::path write(const std::string& script, const std::string& name, const std::string& options) {
    const std::filesystem::path out = dir() / name;
    std::filesystem::remove_all(out);
    EXPECT_TRUE(run_fixture_writer(script, quote_path(dir() / "seq") + " " + quote_path(out) + " " + options +
                                               " --manifest " + quote_path(manifest_of(out))));
    return out;
  }
  static std::filesystem::path manifest_of(const std::filesystem::path& out) { return out.string() + ".jsonl"; }
};

}  // namespace slamvdb::testing
