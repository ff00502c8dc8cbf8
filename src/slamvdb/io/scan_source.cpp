#include "slamvdb/io/scan_source.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/kitti_reader.hpp"
#include "slamvdb/io/pcd.hpp"
#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb {

namespace fs = std::filesystem;

ScanSource open_scan_source(const fs::path& input, double rate_hz) {
  require_exists(input, "scan input");
  if (!fs::is_directory(input)) throw Error(fmt::format("scan input {} is not a directory", input));
  ScanSource source;
  if (fs::is_directory(input / kRellisScanDir) || fs::is_directory(input / kKittiScanDir)) {
    Sequence seq = read_sequence(input);
    source.kind = seq.layout;
    for (const ScanRecord& r : seq.scans) source.scans.push_back({r.stamp, r.points});
    source.ground_truth = std::move(seq.poses);
    source.notes = std::move(seq.notes);
    return source;
  }
  source.kind = "folder";
  const auto bins = list_files(input, ".bin");
  const auto pcds = list_files(input, ".pcd");
  if (!bins.empty() && !pcds.empty())
    throw Error(fmt::format("{} holds both .bin ({}) and .pcd ({}) scans; put one kind per folder", input, bins.size(),
                            pcds.size()));
  const auto& files = bins.empty() ? pcds : bins;
  if (files.empty())
    throw Error(fmt::format("{} holds no scans: no .bin or .pcd files, and no {}/ or {}/ folder of a dataset", input,
                            kRellisScanDir, kKittiScanDir));
  std::vector<double> stamps;
  if (const fs::path times = input / "times.txt"; fs::exists(times)) {
    stamps = read_stamps(times);
    if (stamps.size() != files.size())
      throw Error(fmt::format("{} has {} stamps but {} has {} scans", times, stamps.size(), input, files.size()));
  } else {
    if (!(rate_hz > 0.0)) throw Error(fmt::format("scan rate {} Hz must be > 0", rate_hz));
    for (std::size_t i = 0; i < files.size(); ++i) stamps.push_back(static_cast<double>(i) / rate_hz);
    source.notes.push_back(fmt::format("no times.txt in {}: scan i is stamped i / {} Hz", input, rate_hz));
  }
  for (std::size_t i = 0; i < files.size(); ++i) source.scans.push_back({stamps[i], files[i]});
  return source;
}

ScanPoints load_scan_points(const ScanFile& scan) {
  ScanPoints out;
  if (scan.path.extension() == ".pcd") {
    PcdCloud cloud = read_pcd(scan.path);
    out.points = std::move(cloud.points);
    out.time = std::move(cloud.time);
  } else {
    LidarScan s = read_scan(ScanRecord{scan.stamp, scan.path, {}});
    out.points = std::move(s.points);
  }
  return out;
}

}  // namespace slamvdb
