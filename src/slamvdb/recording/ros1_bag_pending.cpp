// TEMPORARY, until the ROS 1 bag reader (ros1_bag.cpp, written on another branch) is merged: the
// coordinator deletes this file then (its definition of open_ros1_bag replaces this one).
#include <fmt/format.h>
#include <fmt/std.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path) {
  throw Error(fmt::format("ROS 1 bag {}: this build does not read ROS 1 bags yet", path));
}

}  // namespace slamvdb::recording
