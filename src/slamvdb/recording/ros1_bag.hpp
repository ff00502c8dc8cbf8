#pragma once
// ROS 1 bags (format 2.0), read without ROS: uncompressed, bz2 and lz4 chunks.
//
// Hand-written (about 1 100 lines with comments, on liblz4 and libbz2) rather than with Debian's
// librosbag-storage-dev: that library brings roscpp_serialization, Boost (filesystem, regex,
// date_time, program_options), console_bridge, pluginlib and gpgme along; it refuses a bag without its
// index (a recording killed before the end) until `rosbag reindex` rewrites it; and it loads the
// index entry of every message of the bag into std::multisets when it opens it (memory grows with
// the recording). This reader keeps one small record per chunk, holds only the chunks whose times
// overlap, within a memory budget, and reads an unindexed bag linearly instead of refusing it.
//
// Time order: the chunk info records of the index give each chunk's time span; chunks are opened
// when reading reaches their start time and their messages merged, so that messages come in
// log-time order across chunks (equal times in the order written). Within a chunk the records
// are scanned after decompression (which also checks them); the per-chunk index data records
// repeat what that scan finds and are not read. Without an index (index_pos 0: the recorder was
// killed; or past the end: the file was cut), the records are read in file order, each chunk's
// messages in time order, and what a cut or unfinished last chunk still holds is recovered; notes()
// says so.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string_view>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

// The first bytes of a ROS 1 bag of the version read here.
inline constexpr std::string_view kRos1BagMagic = "#ROSBAG V2.0\n";

struct Ros1BagOptions {
  // Decompressed chunks held at once (chunks whose times overlap are read together). Beyond it,
  // the chunk needed last is dropped and decompressed again when its turn comes; a single chunk
  // larger than the budget is still read.
  std::uint64_t chunk_memory_bytes = std::uint64_t{256} << 20;
};

// Opens a ROS 1 bag; throws Error naming the path when it is not one (or of format 1.2), or its
// header is damaged. Reading through next() throws Error on damage (a chunk whose data do not
// decompress, an unknown compression, a record that does not parse) naming the file and offset.
std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path);
std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path, const Ros1BagOptions& options);

}  // namespace slamvdb::recording
