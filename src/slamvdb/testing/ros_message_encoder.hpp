#pragma once
// For tests only: ROS messages serialized by encoders that are not slamvdb's (npm
// @foxglove/rosmsg-serialization for ROS 1, @foxglove/rosmsg2-serialization for CDR little- and
// big-endian), through tests/recording_fixtures/encode_messages.mjs, so that the decoders are
// checked against independent writers of both serializations.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

struct EncodedMessage {
  std::vector<std::uint8_t> ros1, cdr_le, cdr_be;
};

// One serialized form of a message, for tests that run over all three.
struct MessageBytes {
  std::string form;  // "ROS 1", "CDR LE", "CDR BE"
  recording::Serialization serialization;
  const std::vector<std::uint8_t>* bytes;
};
inline std::vector<MessageBytes> forms_of(const EncodedMessage& m) {
  return {{"ROS 1", recording::Serialization::kRos1, &m.ros1},
          {"CDR LE", recording::Serialization::kCdr, &m.cdr_le},
          {"CDR BE", recording::Serialization::kCdr, &m.cdr_be}};
}

inline const std::filesystem::path kRecordingFixtures =
    std::filesystem::path(SLAMVDB_SOURCE_DIR) / "tests" / "recording_fixtures";

// Encodes every message of `spec` ({"messages": [{"name", "type", "message", "cloud"|"image"}]}:
// see encode_messages.mjs) into `out` by name; fails the calling test when the encoder cannot run
// (scripts/setup.sh installs node and the locked npm packages).
inline void encode_ros_messages(const nlohmann::json& spec, const std::filesystem::path& work_dir,
                                std::map<std::string, EncodedMessage>& out) {
  namespace fs = std::filesystem;
  ASSERT_TRUE(fs::exists(kRecordingFixtures / "node_modules" / "@foxglove" / "rosmsg2-serialization"))
      << "the npm encoders are missing: npm ci --prefix tests/recording_fixtures (scripts/setup.sh does it)";
  fs::create_directories(work_dir);
  const fs::path input = work_dir / "messages.json";
  std::ofstream(input) << spec.dump();
  const CommandResult r = run_command(
      "exec node " + quote_path(kRecordingFixtures / "encode_messages.mjs") + " " + quote_path(input) + " " +
          quote_path(work_dir / "encoded"),
      120.0);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto read = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
  };
  for (const auto& m : spec["messages"]) {
    const std::string name = m["name"];
    const fs::path base = work_dir / "encoded" / name;
    out[name] = {read(base.string() + ".ros1"), read(base.string() + ".cdr"), read(base.string() + ".cdr_be")};
    ASSERT_FALSE(out[name].ros1.empty()) << name;
  }
}

}  // namespace slamvdb::testing
