// The MCAP reader on files written by @mcap/core (tests/recording_fixtures/write_mcap.mjs) from a
// small SIMULATED sequence: every form the writer makes reads back message for message (topic,
// type, log time, bytes), in log-time order; chunk selection skips chunks; damage is an Error
// naming the file and the place, or a recovery with a note.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"

namespace slamvdb::recording {
namespace {

namespace fs = std::filesystem;
using testing::quote_path;

class McapFixture : public testing::RecordingFixtureTest {
 protected:
  static fs::path write(const std::string& name, const std::string& options) {
    return RecordingFixtureTest::write("write_mcap.mjs", name + ".mcap", options);
  }
};

// --- every form -----------------------------------------------------------------------------

struct McapForm {
  std::string name, options;
  bool ros2;
  std::string note;  // what the notes must say ("": nothing)
};

void PrintTo(const McapForm& form, std::ostream* os) { *os << form.name; }  // test names, not bytes

class McapForms : public McapFixture, public ::testing::WithParamInterface<McapForm> {};

TEST_P(McapForms, ReadsBackEveryMessageInLogTimeOrder) {
  const McapForm& form = GetParam();
  const fs::path file = write(form.name, form.options);
  const auto written = testing::read_manifest(manifest_of(file));
  ASSERT_EQ(written.size(), 15u);  // tf, 4 scans + 4 odometry, 2 x (image, camera info, labels)
  const auto reader = open_mcap(file);

  const Serialization serialization = form.ros2 ? Serialization::kCdr : Serialization::kRos1;
  ASSERT_NO_FATAL_FAILURE(testing::expect_channels_of(*reader, written, serialization));
  for (const Channel& c : reader->channels())
    EXPECT_NE(c.definition.find(form.ros2 ? "builtin_interfaces/Time stamp" : "uint32 seq"), std::string::npos)
        << c.topic << ": " << c.definition;
  const auto expected = testing::in_log_time_order(written);

  EXPECT_TRUE(testing::same_messages(expected, testing::read_all(*reader)));
  Message m;
  EXPECT_FALSE(reader->next(m));  // and stays at the end
  // Everything once; twice without a summary (a first pass lists the channels).
  EXPECT_LE(reader->bytes_read(), (form.note.empty() ? 1.01 : 2.02) * static_cast<double>(reader->size_bytes()));
  EXPECT_EQ(reader->size_bytes(), fs::file_size(file));
  const std::string notes = testing::notes_text(*reader);
  if (form.note.empty()) {
    EXPECT_EQ(notes, "");
  } else {
    EXPECT_NE(notes.find(form.note), std::string::npos) << notes;
    EXPECT_NE(notes.find(file.string()), std::string::npos) << notes;
  }
  EXPECT_NE(reader->describe().find(form.ros2 ? "ros2" : "ros1"), std::string::npos) << reader->describe();
}

INSTANTIATE_TEST_SUITE_P(
    AllForms, McapForms,
    ::testing::Values(McapForm{"ros1_none", "--profile ros1", false, ""},
                      McapForm{"ros1_lz4", "--profile ros1 --compression lz4", false, ""},
                      McapForm{"ros1_zstd", "--profile ros1 --compression zstd", false, ""},
                      McapForm{"ros2_none", "--profile ros2", true, ""},
                      McapForm{"ros2_lz4", "--profile ros2 --compression lz4 --chunk-size 100000", true, ""},
                      McapForm{"ros2_zstd", "--profile ros2 --compression zstd", true, ""},
                      McapForm{"ros2_big_endian", "--profile ros2 --big-endian --compression zstd", true, ""},
                      McapForm{"ros1_none_no_summary", "--profile ros1 --no-summary", false, "no summary"},
                      McapForm{"ros1_lz4_no_summary", "--profile ros1 --compression lz4 --no-summary", false, "no summary"},
                      McapForm{"ros2_zstd_no_summary", "--profile ros2 --compression zstd --no-summary", true, "no summary"},
                      McapForm{"ros2_unchunked", "--profile ros2 --unchunked", true, "no chunk index"},
                      McapForm{"ros1_unchunked_no_summary", "--profile ros1 --unchunked --no-summary", false, "no summary"},
                      // Topic after topic in one chunk: messages out of log-time order inside it.
                      McapForm{"ros2_one_chunk_by_topic", "--order by-topic --chunk-size 100000000", true, ""},
                      // Topic after topic in small chunks: chunks overlapping in time, merged by the index.
                      McapForm{"ros1_zstd_overlapping", "--profile ros1 --compression zstd --order by-topic --chunk-size 50000",
                           false, ""}),
    [](const auto& info) { return info.param.name; });

// --- other encodings, selection ----------------------------------------------------------------

TEST_F(McapFixture, ChannelsInOtherEncodingsAreListedAsOther) {
  const fs::path file = write("json", "--json-channel --compression lz4");
  const auto reader = open_mcap(file);
  const auto c = std::find_if(reader->channels().begin(), reader->channels().end(),
                              [](const Channel& c) { return c.topic == "/diagnostics_json"; });
  ASSERT_NE(c, reader->channels().end());
  EXPECT_EQ(c->serialization, Serialization::kOther);
  EXPECT_EQ(c->encoding, "json");
  EXPECT_EQ(c->type, "Diagnostics");  // the schema's name
  EXPECT_EQ(c->definition, "");        // not a ROS definition
  EXPECT_TRUE(testing::same_messages(testing::in_log_time_order(testing::read_manifest(manifest_of(file))),
                                     testing::read_all(*reader)));
}

TEST_F(McapFixture, SelectingAChannelSkipsTheChunksWithoutIt) {
  // Topic after topic in small chunks: the clouds fill chunks of their own.
  const fs::path file = write("by_topic", "--order by-topic --chunk-size 50000 --compression zstd");
  const auto written = testing::in_log_time_order(testing::read_manifest(manifest_of(file)));
  std::vector<testing::WrittenMessage> odometry;
  for (const auto& w : written)
    if (w.topic == "/ground_truth/odom") odometry.push_back(w);

  const auto all = open_mcap(file);
  testing::read_all(*all);
  const auto reader = open_mcap(file);
  std::set<std::uint32_t> ids;
  for (const Channel& c : reader->channels())
    if (c.topic == "/ground_truth/odom") ids.insert(c.id);
  ASSERT_EQ(ids.size(), 1u);
  reader->select(ids);
  EXPECT_TRUE(testing::same_messages(odometry, testing::read_all(*reader)));
  // The clouds' chunks (most of the file) were not read.
  EXPECT_GT(all->bytes_read(), fs::file_size(file) * 8 / 10);
  EXPECT_LT(reader->bytes_read(), fs::file_size(file) / 5) << reader->bytes_read() << " of " << fs::file_size(file);

  // Selecting all channels again delivers the other topics from there on, still in time order.
  const auto again = open_mcap(file);
  again->select(ids);
  Message m;
  ASSERT_TRUE(again->next(m));
  again->select({});
  const auto rest = testing::read_all(*again);
  EXPECT_TRUE(std::any_of(rest.begin(), rest.end(), [](const auto& r) { return r.topic == "/os1_cloud_node/points"; }));
  EXPECT_TRUE(std::is_sorted(rest.begin(), rest.end(), [](const auto& a, const auto& b) { return a.log_time_ns < b.log_time_ns; }));
  EXPECT_GE(rest.front().log_time_ns, m.log_time_ns);
}

TEST_F(McapFixture, LinearReadingSaysWhenChunksOverlapBeyondWhatItCanReorder) {
  // Without an index, topic-after-topic chunks cannot be put back in time order: every message is
  // still delivered, and the notes count those that came out early.
  const fs::path file = write("overlap_linear", "--order by-topic --chunk-size 50000 --no-summary");
  const auto written = testing::read_manifest(manifest_of(file));
  const auto reader = open_mcap(file);
  auto read = testing::read_all(*reader);
  ASSERT_EQ(read.size(), written.size());
  std::multiset<std::tuple<std::string, std::int64_t, std::uint32_t>> a, b;
  for (const auto& w : written) a.emplace(w.topic, w.log_time_ns, w.crc32);
  for (const auto& r : read) b.emplace(r.topic, r.log_time_ns, r.crc32);
  EXPECT_EQ(a, b);
  EXPECT_NE(testing::notes_text(*reader).find("came out earlier in log time"), std::string::npos) << testing::notes_text(*reader);
}

}  // namespace
}  // namespace slamvdb::recording
