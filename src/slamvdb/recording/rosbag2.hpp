#pragma once
// ROS 2 bags read without ROS (rosbag2 is not packaged in Debian 12; SQLite, yaml-cpp and zstd are):
// a bag folder (metadata.yaml and one or more .db3 files, or .mcap files for the mcap storage), or
// a single .db3 file without its metadata (topics and types from its own tables).
//  - Split bags: the files are merged by timestamp (equal times in file order), each opened when
//    the merge reaches its start time (from metadata.yaml), so few are open at once.
//  - compression_mode FILE (each file zstd-compressed whole, "x_0.db3.zstd"): SQLite needs a real
//    file, so each is decompressed to a temporary copy in $TMPDIR while it is read and deleted
//    after; disk use is bounded by the files open at once (one, for a bag split in time order),
//    and said in notes().
//  - compression_mode MESSAGE: each message's data is a zstd frame, decompressed as it is read.
// Types are normalised to ROS 1 form ("sensor_msgs/msg/PointCloud2" -> "sensor_msgs/PointCloud2").
#include <filesystem>
#include <memory>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

// Throws Error naming the path when it is neither form, a listed file is missing, or it is damaged.
std::unique_ptr<RecordingReader> open_rosbag2(const std::filesystem::path& path);

}  // namespace slamvdb::recording
