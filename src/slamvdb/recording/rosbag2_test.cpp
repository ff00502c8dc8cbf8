// The ROS 2 bag reader on bags written by tests/recording_fixtures/write_rosbag2.mjs (CDR by
// @foxglove/rosmsg2-serialization, the .db3 files by Python's sqlite3 with rosbag2's tables, the
// metadata.yaml as rosbag2 writes it) from a small SIMULATED sequence.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/rosbag2.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb::recording {
namespace {

namespace fs = std::filesystem;
using testing::error_of;
using testing::quote_path;

class Rosbag2Fixture : public testing::RecordingFixtureTest {
 protected:
  static fs::path write(const std::string& name, const std::string& options) {
    return RecordingFixtureTest::write("write_rosbag2.mjs", name, options);
  }
};

// Runs SQL on a .db3 with Python's sqlite3 (as the fixture writer does).
void run_sql(const fs::path& db3, const std::string& sql) {
  const auto r = testing::run_command("exec python3 -c " +
                                      testing::shell_quote("import sqlite3,sys; d=sqlite3.connect(sys.argv[1]); "
                                                           "d.executescript(sys.argv[2]); d.commit()") +
                                      " " + quote_path(db3) + " " + testing::shell_quote(sql) + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

struct Rosbag2Form {
  std::string name, options;
  int files;
  bool definitions;  // schema version 4 (Iron on) keeps the message definitions
};
void PrintTo(const Rosbag2Form& form, std::ostream* os) { *os << form.name; }  // test names, not bytes

class Rosbag2Forms : public Rosbag2Fixture, public ::testing::WithParamInterface<Rosbag2Form> {};

TEST_P(Rosbag2Forms, ReadsBackEveryMessageInTimeOrder) {
  const Rosbag2Form& form = GetParam();
  const fs::path bag = write(form.name, form.options);
  const auto written = testing::read_manifest(manifest_of(bag));
  ASSERT_EQ(written.size(), 15u);
  std::size_t db3_files = 0;
  for (const auto& e : fs::directory_iterator(bag)) db3_files += e.path().filename().string().find(".db3") != std::string::npos;
  ASSERT_EQ(db3_files, static_cast<std::size_t>(form.files));

  const auto reader = open_rosbag2(bag);
  ASSERT_NO_FATAL_FAILURE(testing::expect_channels_of(*reader, written, Serialization::kCdr));
  const auto expected = testing::in_log_time_order(written);
  EXPECT_TRUE(testing::same_messages(expected, testing::read_all(*reader)));
  // Definitions come with the first file opened (schema version 4 keeps them).
  for (const Channel& c : reader->channels())
    EXPECT_EQ(c.definition.empty(), !form.definitions) << c.topic << ": " << c.definition;
  EXPECT_NE(reader->describe().find(std::to_string(form.files) + " file"), std::string::npos) << reader->describe();
  EXPECT_EQ(reader->bytes_read(), reader->size_bytes());
  const std::string notes = testing::notes_text(*reader);
  if (form.options.find("zstd-file") != std::string::npos)
    EXPECT_NE(notes.find("decompressed to a temporary copy"), std::string::npos) << notes;
  else
    EXPECT_EQ(notes, "");
}

INSTANTIATE_TEST_SUITE_P(
    AllForms, Rosbag2Forms,
    ::testing::Values(Rosbag2Form{"one_file", "", 1, true}, Rosbag2Form{"two_files", "--split 2", 2, true},
                      Rosbag2Form{"three_files_humble", "--split 3 --ros-distro humble", 3, false},
                      Rosbag2Form{"file_compression", "--split 2 --compression zstd-file", 2, true},
                      Rosbag2Form{"message_compression", "--split 2 --compression zstd-message --ros-distro iron", 2, true},
                      Rosbag2Form{"big_endian", "--big-endian --ros-distro humble", 1, false}),
    [](const auto& info) { return info.param.name; });

TEST_F(Rosbag2Fixture, FilesOverlappingInTimeAreMerged) {
  // Two files, the second's messages moved 150 ms earlier (metadata.yaml says so): they interleave.
  const fs::path bag = write("overlap", "--split 2");
  auto written = testing::read_manifest(manifest_of(bag));
  const std::size_t first_file = (written.size() + 1) / 2;  // the writer's split
  constexpr std::int64_t kShift = 150'000'000;
  run_sql(bag / "overlap_1.db3", "UPDATE messages SET timestamp = timestamp - " + std::to_string(kShift));
  for (std::size_t i = first_file; i < written.size(); ++i) written[i].log_time_ns -= kShift;
  YAML::Node metadata = YAML::LoadFile((bag / "metadata.yaml").string());
  YAML::Node start = metadata["rosbag2_bagfile_information"]["files"][1]["starting_time"]["nanoseconds_since_epoch"];
  start = start.as<std::int64_t>() - kShift;
  std::ofstream(bag / "metadata.yaml") << metadata;

  const auto expected = testing::in_log_time_order(written);
  ASSERT_NE(expected, written);  // the shift did interleave them
  const auto reader = open_rosbag2(bag);
  EXPECT_TRUE(testing::same_messages(expected, testing::read_all(*reader)));
}

TEST_F(Rosbag2Fixture, SingleDb3FileWithoutMetadataReadsByItsOwnTables) {
  for (const std::string compression : {"none", "zstd-message"}) {
    SCOPED_TRACE(compression);
    const fs::path bag = write("lone_" + compression, "--no-metadata --compression " + compression);
    const fs::path db3 = bag / ("lone_" + compression + "_0.db3");
    const auto written = testing::read_manifest(manifest_of(bag));
    const auto reader = open_rosbag2(db3);
    std::map<std::string, std::uint64_t> count;
    for (const auto& w : written) ++count[w.topic];
    ASSERT_EQ(reader->channels().size(), count.size());
    for (const Channel& c : reader->channels()) EXPECT_EQ(c.message_count, count[c.topic]) << c.topic;
    EXPECT_TRUE(testing::same_messages(testing::in_log_time_order(written), testing::read_all(*reader)));
    EXPECT_NE(reader->describe().find("single sqlite3 .db3 file"), std::string::npos);
    const std::string notes = testing::notes_text(*reader);
    EXPECT_EQ(notes.find("zstd frames") != std::string::npos, compression != "none") << notes;
  }
}

TEST_F(Rosbag2Fixture, McapStorageFolderIsReadThroughTheMcapReader) {
  // rosbag2's mcap storage (the default from Iron): the folder holds .mcap files (ros2 profile).
  const fs::path mcap = RecordingFixtureTest::write("write_mcap.mjs", "part.mcap", "--compression zstd");
  const auto written = testing::read_manifest(manifest_of(mcap));
  const fs::path bag = dir() / "mcap_bag";
  fs::create_directories(bag);
  fs::rename(mcap, bag / "mcap_bag_0.mcap");
  const auto expected = testing::in_log_time_order(written);
  const std::int64_t start = expected.front().log_time_ns, duration = expected.back().log_time_ns - start;
  std::map<std::string, std::pair<std::string, int>> topics;
  for (const auto& w : written) {
    topics[w.topic].first = w.type.substr(0, w.type.find('/')) + "/msg" + w.type.substr(w.type.find('/'));
    ++topics[w.topic].second;
  }
  std::string yaml = "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  duration:\n    nanoseconds: " +
                     std::to_string(duration) + "\n  starting_time:\n    nanoseconds_since_epoch: " + std::to_string(start) +
                     "\n  message_count: " + std::to_string(written.size()) + "\n  topics_with_message_count:\n";
  for (const auto& [topic, t] : topics)
    yaml += "    - topic_metadata:\n        name: " + topic + "\n        type: " + t.first +
            "\n        serialization_format: cdr\n        offered_qos_profiles: \"\"\n        type_description_hash: \"\"\n"
            "      message_count: " + std::to_string(t.second) + "\n";
  yaml += "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - mcap_bag_0.mcap\n  files:\n"
          "    - path: mcap_bag_0.mcap\n      starting_time:\n        nanoseconds_since_epoch: " + std::to_string(start) +
          "\n      duration:\n        nanoseconds: " + std::to_string(duration) + "\n      message_count: " +
          std::to_string(written.size()) + "\n  custom_data: ~\n  ros_distro: iron\n";
  std::ofstream(bag / "metadata.yaml") << yaml;
  const auto reader = open_rosbag2(bag);
  EXPECT_EQ(reader->describe(), "ROS 2 bag (mcap storage, 1 file)");
  EXPECT_TRUE(testing::same_messages(expected, testing::read_all(*reader)));
  for (const Channel& c : reader->channels()) EXPECT_FALSE(c.definition.empty()) << c.topic;  // from the MCAP schemas
}

TEST_F(Rosbag2Fixture, SelectingATopicReadsOnlyIt) {
  const fs::path bag = write("select", "--split 2 --compression zstd-message");
  const auto written = testing::in_log_time_order(testing::read_manifest(manifest_of(bag)));
  const std::string topic = "/pylon_camera_node/image_raw/compressed";
  auto images_after = [&](std::size_t first) {
    std::vector<testing::WrittenMessage> images;
    for (std::size_t i = first; i < written.size(); ++i)
      if (written[i].topic == topic) images.push_back(written[i]);
    return images;
  };
  auto id_of = [&](const RecordingReader& r) {
    for (const Channel& c : r.channels())
      if (c.topic == topic) return c.id;
    ADD_FAILURE() << "no channel " << topic;
    return std::uint32_t{0};
  };
  const auto reader = open_rosbag2(bag);
  reader->select({id_of(*reader)});
  EXPECT_TRUE(testing::same_messages(images_after(0), testing::read_all(*reader)));

  // Selected while reading, with both files open: the rest of the images, their bytes intact.
  const auto midway = open_rosbag2(bag);
  Message m;
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(midway->next(m));
  midway->select({id_of(*midway)});
  auto rest = testing::read_all(*midway);
  const auto expected = images_after(8);
  ASSERT_EQ(rest.size(), expected.size());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    EXPECT_EQ(rest[i].log_time_ns, expected[i].log_time_ns);
    EXPECT_EQ(rest[i].crc32, expected[i].crc32);
  }
}

TEST_F(Rosbag2Fixture, MissingFileIsAnErrorNamingIt) {
  const fs::path bag = write("missing", "--split 2");
  fs::remove(bag / "missing_1.db3");
  const std::string error = error_of([&] { open_rosbag2(bag); });
  EXPECT_NE(error.find("lists the file missing_1.db3, which does not exist"), std::string::npos) << error;
  EXPECT_NE(error.find(bag.string()), std::string::npos) << error;
}

TEST_F(Rosbag2Fixture, DamagedMetadataIsAnErrorNamingTheField) {
  const fs::path bag = write("metadata", "");
  const std::string yaml = testing::read_text_file(bag / "metadata.yaml");
  auto with = [&](const std::string& from, const std::string& to) {
    std::string changed = yaml;
    const std::size_t at = changed.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    changed.replace(at, from.size(), to);
    std::ofstream(bag / "metadata.yaml") << changed;
    return error_of([&] { testing::read_all(*open_rosbag2(bag)); });
  };
  EXPECT_NE(with("storage_identifier: sqlite3", "storage_identifier: rosbag_v2").find("\"rosbag_v2\""),
            std::string::npos);
  EXPECT_NE(with("compression_format: \"\"\n  compression_mode: \"\"",
                 "compression_format: \"lz5\"\n  compression_mode: \"FILE\"")
                .find("compression_format \"lz5\""),
            std::string::npos);
  EXPECT_NE(with("rosbag2_bagfile_information:", "something_else:").find("no rosbag2_bagfile_information"),
            std::string::npos);
  EXPECT_NE(with("  version: 9", "  version: [1, 2").find("metadata.yaml"), std::string::npos);
}

TEST_F(Rosbag2Fixture, DamagedDatabaseIsAnErrorNamingTheFile) {
  {  // A message whose zstd frame is cut short.
    const fs::path bag = write("damaged_message", "--split 2 --compression zstd-message");
    run_sql(bag / "damaged_message_0.db3", "UPDATE messages SET data = substr(data, 1, 20) WHERE id = 2");
    const std::string error = error_of([&] { testing::read_all(*open_rosbag2(bag)); });
    EXPECT_NE(error.find("message 1 (topic /os1_cloud_node/points"), std::string::npos) << error;
    EXPECT_NE(error.find("zstd"), std::string::npos) << error;
  }
  {  // The second file cut in half.
    const fs::path bag = write("damaged_file", "--split 2");
    const fs::path db3 = bag / "damaged_file_1.db3";
    fs::resize_file(db3, fs::file_size(db3) / 2);
    const std::string error = error_of([&] { testing::read_all(*open_rosbag2(bag)); });
    EXPECT_NE(error.find(db3.string()), std::string::npos) << error;
  }
  {  // An SQLite database that is not a bag, and a file that is not a database.
    const fs::path other = dir() / "other.db3";
    run_sql(other, "CREATE TABLE t(x);");
    EXPECT_NE(error_of([&] { open_rosbag2(other); }).find("not a ROS 2 bag: it has no topics table"), std::string::npos);
    std::ofstream(dir() / "text.db3") << std::string(5000, 'x');
    EXPECT_NE(error_of([&] { open_rosbag2(dir() / "text.db3"); }).find("text.db3"), std::string::npos);
  }
}

TEST_F(Rosbag2Fixture, FileCompressionUsesOneTemporaryCopyAtATimeAndRemovesIt) {
  const fs::path bag = write("temporary", "--split 3 --compression zstd-file");
  fs::path copies;
  {
    const auto reader = open_rosbag2(bag);
    EXPECT_EQ(testing::read_all(*reader).size(), 15u);
    const std::string notes = testing::notes_text(*reader);
    const std::size_t at = notes.find("temporary copy in \"");
    ASSERT_NE(at, std::string::npos) << notes;
    const std::size_t from = at + std::string("temporary copy in \"").size();
    copies = notes.substr(from, notes.find('"', from) - from);
    EXPECT_TRUE(fs::is_directory(copies)) << copies;
    // Files split in time order: the next is opened when the merge reaches its first message,
    // with the previous one's last message (at the same stamp) possibly still to come.
    EXPECT_TRUE(notes.find("at most 1 at once") != std::string::npos || notes.find("at most 2 at once") != std::string::npos)
        << notes;
  }
  EXPECT_FALSE(fs::exists(copies)) << copies;
}

}  // namespace
}  // namespace slamvdb::recording
