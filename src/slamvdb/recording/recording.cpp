// Which container a path is (by its first bytes, not its name) and the reader for it.
#include "slamvdb/recording/recording.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <cstring>
#include <system_error>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/recording/rosbag2.hpp"

namespace slamvdb::recording {

// The ROS 1 bag reader (ros1_bag.cpp, written beside this part's other containers).
std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path);

namespace recording_cpp {

enum class Container { kNone, kMcap, kRos1Bag, kSqlite, kRosbag2Folder };

constexpr char kMcapMagic[] = "\x89MCAP0\r\n";
constexpr char kRos1Magic[] = "#ROSBAG V2.0\n";
constexpr char kSqliteMagic[] = "SQLite format 3";  // and a NUL: 16 bytes

bool starts_with(const std::string& bytes, const char* magic, std::size_t size) {
  return bytes.size() >= size && std::memcmp(bytes.data(), magic, size) == 0;
}

// The container at `path`; kNone when it is none (or cannot be read: open_recording then says why).
Container container_of(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return std::filesystem::is_regular_file(path / "metadata.yaml", ec) ? Container::kRosbag2Folder : Container::kNone;
  if (!std::filesystem::is_regular_file(path, ec)) return Container::kNone;
  std::string head(16, '\0');
  try {
    RegularFile file(path, "recording");
    if (file.size() < 8) return Container::kNone;
    head.resize(static_cast<std::size_t>(std::min<std::uint64_t>(file.size(), head.size())));
    file.read_exact(head.data(), head.size());
  } catch (const Error&) {
    return Container::kNone;
  }
  if (starts_with(head, kMcapMagic, 8)) return Container::kMcap;
  if (starts_with(head, kRos1Magic, sizeof kRos1Magic - 1)) return Container::kRos1Bag;
  if (starts_with(head, kSqliteMagic, sizeof kSqliteMagic)) return Container::kSqlite;  // with its NUL
  return Container::kNone;
}

}  // namespace recording_cpp

bool is_recording(const std::filesystem::path& path) {
  return recording_cpp::container_of(path) != recording_cpp::Container::kNone;
}

std::unique_ptr<RecordingReader> open_recording(const std::filesystem::path& path) {
  using recording_cpp::Container;
  switch (recording_cpp::container_of(path)) {
    case Container::kMcap: return open_mcap(path);
    case Container::kRos1Bag: return open_ros1_bag(path);
    case Container::kSqlite:
    case Container::kRosbag2Folder: return open_rosbag2(path);
    case Container::kNone: break;
  }
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error(fmt::format("recording {} is a folder without metadata.yaml, so not a ROS 2 bag", path));
  require_regular_file(path, "recording");  // throws: missing, a FIFO, ...
  throw Error(fmt::format("recording {} is none of the recordings slamvdb reads: its first bytes are not those of a "
                          "ROS 1 bag (#ROSBAG V2.0), an MCAP file or a ROS 2 bag's SQLite database",
                          path));
}

std::string ros1_type_name(std::string_view type) {
  // "pkg/msg/Name" -> "pkg/Name"; ROS 2 IDL's "pkg::msg::Name" likewise.
  for (const std::string_view middle : {std::string_view("/msg/"), std::string_view("::msg::")}) {
    const std::size_t at = type.find(middle);
    if (at != std::string_view::npos && at > 0 && type.find('/', at + middle.size()) == std::string_view::npos &&
        type.find("::", at + middle.size()) == std::string_view::npos)
      return std::string(type.substr(0, at)) + "/" + std::string(type.substr(at + middle.size()));
  }
  return std::string(type);
}

}  // namespace slamvdb::recording
