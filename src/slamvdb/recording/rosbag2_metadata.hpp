#pragma once
// A ROS 2 bag folder's metadata.yaml (rosbag2_bagfile_information), as rosbag2 writes it from
// Foxy to Jazzy (versions 4 to 9): the storage, the files in order, each file's start time when
// given (version 5+), the topics with their types and message counts, and the compression.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

struct Rosbag2File {
  std::filesystem::path path;             // resolved against the folder; checked to exist
  std::optional<std::int64_t> start_ns;   // from `files:` (version 5+)
};

struct Rosbag2Metadata {
  int version = 0;
  std::string storage;             // "sqlite3" or "mcap"
  std::string compression_format;  // "" or "zstd"
  std::string compression_mode;    // "", "FILE" or "MESSAGE"
  std::vector<Rosbag2File> files;
  std::vector<Channel> topics;     // id = position; message_count from the metadata
  std::optional<TimeRange> range;
};

// Throws Error naming the file and the field when it is not rosbag2 metadata, uses a storage or
// compression this reader does not know, or lists a file that does not exist.
Rosbag2Metadata read_rosbag2_metadata(const std::filesystem::path& folder);

}  // namespace slamvdb::recording
