// Seeds of the recording harnesses (fuzz_mcap, fuzz_rosbag2): small MCAP files assembled record
// by record (testing/mcap_assembly.hpp; the project has no MCAP writer, the tests use @mcap/core's), in each form the reader has a path for (indexed, no summary, messages outside
// chunks, zstd and lz4 chunks), and ROS 2 bags made with SQLite's C API (rosbag2's tables).
#include <fmt/format.h>
#include <lz4frame.h>
#include <sqlite3.h>
#include <zstd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "slamvdb/testing/mcap_assembly.hpp"

namespace fs = std::filesystem;

namespace seeds_recording {

void put(const fs::path& dir, const std::string& name, const std::string& bytes) {
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary) << bytes;
}

using namespace slamvdb::testing::mcap_assembly;

std::string compress(const std::string& how, const std::string& raw) {
  std::string out;
  if (how == "zstd") {
    out.resize(ZSTD_compressBound(raw.size()));
    out.resize(ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), 3));
  } else if (how == "lz4") {
    out.resize(LZ4F_compressFrameBound(raw.size(), nullptr));
    out.resize(LZ4F_compressFrame(out.data(), out.size(), raw.data(), raw.size(), nullptr));
  } else {
    out = raw;
  }
  return out;
}

// magic, header, [chunk + message index | loose records], data end, [summary], footer, magic.
std::string mcap_file(const std::string& compression, bool chunked, bool summary) {
  const std::string cdr("\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f", 12);
  const std::string definitions = schema(1, "sensor_msgs/msg/Imu", "ros2msg", "float64 x") + channel(3, 1, "/imu", "cdr");
  const std::string records = definitions + message(3, 20, cdr) + message(3, 10, cdr) + message(3, 30, cdr);
  std::string file = magic() + header("ros2");
  const std::uint64_t chunk_offset = file.size();
  const std::string packed = compress(compression, records);
  const std::string the_chunk = chunk(10, 30, records, compression, packed);
  if (chunked) {
    const std::uint64_t m = message(3, 20, cdr).size();
    file += the_chunk + record(0x07, le<std::uint16_t>(3) + le<std::uint32_t>(48) + le<std::uint64_t>(20) +
                                         le<std::uint64_t>(definitions.size()) + le<std::uint64_t>(10) +
                                         le<std::uint64_t>(definitions.size() + m) + le<std::uint64_t>(30) +
                                         le<std::uint64_t>(definitions.size() + 2 * m));
  } else {
    file += records;
  }
  file += data_end();
  const std::uint64_t summary_start = file.size();
  std::string summary_records;
  if (summary) {
    summary_records = definitions + statistics(3, 10, 30, {{3, 3}});
    if (chunked)
      summary_records += chunk_index(10, 30, chunk_offset, the_chunk.size(), {3}, compression, packed.size(),
                                     records.size());
  }
  return file + summary_records + footer(summary ? summary_start : 0, summary_records);
}

void exec(sqlite3* db, const std::string& sql) {
  char* error = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string message = error ? error : "?";
    sqlite3_free(error);
    throw std::runtime_error("seed database: " + message);
  }
}

// A rosbag2 .db3 (schema version 4) with two topics and four messages; zstd frames as data when
// `zstd` (MESSAGE compression).
std::string db3(const fs::path& scratch, bool zstd) {
  fs::remove(scratch);
  sqlite3* db = nullptr;
  sqlite3_open(scratch.c_str(), &db);
  exec(db,
       "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
       "INSERT INTO schema VALUES(4,'jazzy');"
       "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,metadata TEXT NOT NULL);"
       "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,serialization_format TEXT NOT "
       "NULL,offered_qos_profiles TEXT NOT NULL,type_description_hash TEXT NOT NULL);"
       "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,topic_type TEXT NOT NULL,encoding TEXT NOT NULL,"
       "encoded_message_definition TEXT NOT NULL,type_description_hash TEXT NOT NULL);"
       "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,timestamp INTEGER NOT NULL, data BLOB NOT "
       "NULL);"
       "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
       "INSERT INTO topics VALUES(1,'/imu','sensor_msgs/msg/Imu','cdr','',''),(2,'/odom','nav_msgs/msg/Odometry','cdr','','');"
       "INSERT INTO message_definitions VALUES(1,'sensor_msgs/msg/Imu','ros2msg','float64 x','');");
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", -1, &insert, nullptr);
  const std::string cdr("\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f", 12);
  const std::string data = zstd ? compress("zstd", cdr) : cdr;
  for (const auto& [topic, time] : {std::pair{1, 30}, std::pair{2, 10}, std::pair{1, 20}, std::pair{2, 20}}) {
    sqlite3_bind_int(insert, 1, topic);
    sqlite3_bind_int64(insert, 2, time);
    sqlite3_bind_blob(insert, 3, data.data(), static_cast<int>(data.size()), SQLITE_TRANSIENT);
    sqlite3_step(insert);
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_close(db);
  std::ifstream in(scratch, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(in), {}};
  fs::remove(scratch);
  return bytes;
}

std::string metadata(const std::string& mode) {
  return fmt::format(
      "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  duration:\n    nanoseconds: 20\n"
      "  starting_time:\n    nanoseconds_since_epoch: 10\n  message_count: 4\n  topics_with_message_count:\n"
      "    - topic_metadata:\n        name: /imu\n        type: sensor_msgs/msg/Imu\n        serialization_format: cdr\n"
      "        offered_qos_profiles: \"\"\n      message_count: 2\n    - topic_metadata:\n        name: /odom\n"
      "        type: nav_msgs/msg/Odometry\n        serialization_format: cdr\n        offered_qos_profiles: \"\"\n"
      "      message_count: 2\n  compression_format: \"{}\"\n  compression_mode: \"{}\"\n  relative_file_paths:\n"
      "    - bag_0.db3\n  files:\n    - path: bag_0.db3\n      starting_time:\n        nanoseconds_since_epoch: 10\n"
      "      duration:\n        nanoseconds: 20\n      message_count: 4\n",
      mode.empty() ? "" : "zstd", mode);
}

}  // namespace seeds_recording

void write_recording_seeds(const fs::path& out_dir) {
  using namespace seeds_recording;
  put(out_dir / "mcap", "indexed", mcap_file("", true, true));
  put(out_dir / "mcap", "indexed_zstd", mcap_file("zstd", true, true));
  put(out_dir / "mcap", "indexed_lz4", mcap_file("lz4", true, true));
  put(out_dir / "mcap", "no_summary_zstd", mcap_file("zstd", true, false));
  put(out_dir / "mcap", "unchunked", mcap_file("", false, true));
  put(out_dir / "mcap", "unchunked_no_summary", mcap_file("", false, false));
  const fs::path scratch = out_dir / "seed.db3.tmp";
  put(out_dir / "rosbag2", "db3", std::string(1, '\0') + db3(scratch, false));
  put(out_dir / "rosbag2", "db3_zstd_messages", std::string(1, '\0') + db3(scratch, true));
  for (const auto& [name, mode] : {std::pair{"folder", ""}, std::pair{"folder_zstd_messages", "MESSAGE"}}) {
    const std::string yaml = metadata(mode);
    put(out_dir / "rosbag2", name,
        std::string(1, '\1') + le<std::uint32_t>(static_cast<std::uint32_t>(yaml.size())) + yaml +
            db3(scratch, std::string(mode) == "MESSAGE"));
  }
}
