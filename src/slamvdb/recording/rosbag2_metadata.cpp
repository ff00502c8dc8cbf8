#include "slamvdb/recording/rosbag2_metadata.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <yaml-cpp/yaml.h>

#include <map>
#include <system_error>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb::recording {

namespace rosbag2_metadata_cpp {

constexpr std::uint64_t kMaxMetadataBytes = std::uint64_t{64} << 20;

Serialization serialization_of_format(const std::string& format) {
  if (format == "cdr") return Serialization::kCdr;
  if (format == "ros1") return Serialization::kRos1;
  return Serialization::kOther;
}

// A file named in the metadata: relative to the folder (Humble on); older rosbag2 wrote it
// relative to the folder's parent ("bag/bag_0.db3").
std::filesystem::path resolve(const std::filesystem::path& folder, const std::string& name) {
  std::error_code ec;
  const std::filesystem::path direct = folder / name;
  if (std::filesystem::exists(direct, ec)) return direct;
  const std::filesystem::path by_name = folder / std::filesystem::path(name).filename();
  if (std::filesystem::exists(by_name, ec)) return by_name;
  return direct;
}

}  // namespace rosbag2_metadata_cpp
using namespace rosbag2_metadata_cpp;

Rosbag2Metadata read_rosbag2_metadata(const std::filesystem::path& folder) {
  const std::filesystem::path file = folder / "metadata.yaml";
  const std::string text = read_regular_file(file, "ROS 2 bag metadata", kMaxMetadataBytes);
  Rosbag2Metadata m;
  std::string field = "rosbag2_bagfile_information";
  try {
    const YAML::Node root = YAML::Load(text);
    const YAML::Node info = root.IsMap() ? root["rosbag2_bagfile_information"] : YAML::Node();
    if (!info || !info.IsMap())
      throw Error(fmt::format("ROS 2 bag metadata {} has no rosbag2_bagfile_information: not a ROS 2 bag's metadata", file));
    field = "version";
    m.version = info["version"].as<int>();
    field = "storage_identifier";
    m.storage = info["storage_identifier"].as<std::string>();
    if (m.storage != "sqlite3" && m.storage != "mcap")
      throw Error(fmt::format("ROS 2 bag metadata {}: storage_identifier \"{}\" is not one this reader knows (sqlite3, "
                              "mcap)",
                              file, m.storage));
    field = "compression_format";
    if (info["compression_format"]) m.compression_format = info["compression_format"].as<std::string>();
    field = "compression_mode";
    if (info["compression_mode"]) m.compression_mode = info["compression_mode"].as<std::string>();
    if (m.compression_mode == "NONE") m.compression_mode.clear();
    if (!m.compression_mode.empty() && m.compression_format != "zstd")
      throw Error(fmt::format("ROS 2 bag metadata {}: compression_format \"{}\" is not one this reader knows (zstd)",
                              file, m.compression_format));
    if (!m.compression_mode.empty() && m.compression_mode != "FILE" && m.compression_mode != "MESSAGE")
      throw Error(fmt::format("ROS 2 bag metadata {}: compression_mode \"{}\" is not FILE, MESSAGE or NONE", file,
                              m.compression_mode));

    field = "files";
    std::map<std::string, std::int64_t> start_of_file;
    if (const YAML::Node files = info["files"]; files && files.IsSequence())
      for (const YAML::Node& f : files)
        start_of_file[f["path"].as<std::string>()] = f["starting_time"]["nanoseconds_since_epoch"].as<std::int64_t>();
    field = "relative_file_paths";
    const YAML::Node paths = info["relative_file_paths"];
    if (!paths || !paths.IsSequence() || paths.size() == 0)
      throw Error(fmt::format("ROS 2 bag metadata {} lists no files (relative_file_paths)", file));
    for (const YAML::Node& p : paths) {
      const std::string name = p.as<std::string>();
      Rosbag2File f{resolve(folder, name), std::nullopt};
      if (const auto s = start_of_file.find(name); s != start_of_file.end()) f.start_ns = s->second;
      std::error_code ec;
      if (!std::filesystem::exists(f.path, ec))
        throw Error(fmt::format("ROS 2 bag {}: metadata.yaml lists the file {}, which does not exist", folder, name));
      m.files.push_back(std::move(f));
    }

    field = "topics_with_message_count";
    if (const YAML::Node topics = info["topics_with_message_count"]; topics && topics.IsSequence()) {
      for (const YAML::Node& t : topics) {
        const YAML::Node meta = t["topic_metadata"];
        Channel c;
        c.id = static_cast<std::uint32_t>(m.topics.size());
        c.topic = meta["name"].as<std::string>();
        c.type = ros1_type_name(meta["type"].as<std::string>());
        c.encoding = meta["serialization_format"].as<std::string>();
        c.serialization = serialization_of_format(c.encoding);
        if (t["message_count"]) c.message_count = t["message_count"].as<std::uint64_t>();
        m.topics.push_back(std::move(c));
      }
    }
    field = "starting_time";
    if (info["starting_time"] && info["duration"] && info["message_count"] &&
        info["message_count"].as<std::uint64_t>() > 0) {
      const auto start = info["starting_time"]["nanoseconds_since_epoch"].as<std::int64_t>();
      const auto duration = info["duration"]["nanoseconds"].as<std::int64_t>();
      std::int64_t end = 0;
      if (duration < 0 || __builtin_add_overflow(start, duration, &end))
        throw Error(fmt::format("ROS 2 bag metadata {}: the duration {} ns is negative or ends past the year 2262",
                                file, duration));
      m.range = TimeRange{start, end};
    }
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("ROS 2 bag metadata {}: cannot read {} ({})", file, field, e.what()));
  }
  return m;
}

}  // namespace slamvdb::recording
