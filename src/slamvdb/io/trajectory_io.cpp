#include "slamvdb/io/trajectory_io.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <fstream>
#include <iterator>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb {

std::optional<PoseFormat> parse_pose_format(const std::string& name) {
  if (name == "kitti") return PoseFormat::kKitti;
  if (name == "tum") return PoseFormat::kTum;
  return std::nullopt;
}

StampedPoses read_trajectory(const std::filesystem::path& file, std::optional<PoseFormat> format) {
  require_exists(file, "trajectory file");
  std::ifstream in(file);
  if (!in) throw Error(fmt::format("cannot open {}", file));
  StampedPoses out;
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const std::string where = fmt::format("{}:{}", file.string(), line_no);
    const std::vector<double> v = parse_numbers(line, where);
    if (v.empty()) continue;
    if (!format) {
      if (v.size() == 12) format = PoseFormat::kKitti;
      else if (v.size() == 8) format = PoseFormat::kTum;
      else
        throw Error(fmt::format("{}: {} numbers: neither a KITTI pose (12) nor a TUM pose (8: stamp tx ty tz qx qy qz qw)",
                                where, v.size()));
    }
    if (*format == PoseFormat::kKitti) {
      if (v.size() != 12) throw Error(fmt::format("{}: {} numbers, a KITTI pose has 12", where, v.size()));
      out.poses.push_back(rigid_from_3x4(Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(v.data()), where));
      out.stamps.push_back(static_cast<double>(out.stamps.size()));
    } else {
      if (v.size() != 8) throw Error(fmt::format("{}: {} numbers, a TUM pose has 8 (stamp tx ty tz qx qy qz qw)", where, v.size()));
      const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
      if (std::abs(q.norm() - 1.0) > 1e-3)
        throw Error(fmt::format("{}: quaternion norm {:.6f}, expected a unit quaternion", where, q.norm()));
      Pose T = Pose::Identity();
      T.linear() = q.normalized().toRotationMatrix();
      T.translation() = Vec3d(v[1], v[2], v[3]);
      out.stamps.push_back(v[0]);
      out.poses.push_back(T);
    }
  }
  if (out.poses.empty()) throw Error(fmt::format("trajectory file {} holds no poses", file));
  out.format = *format;
  if (out.format == PoseFormat::kTum) check_increasing(out.stamps, file.string());
  return out;
}

void write_trajectory(const std::filesystem::path& file, const std::vector<double>& stamps,
                      const std::vector<Pose>& poses, PoseFormat format) {
  if (stamps.size() != poses.size())
    throw Error(fmt::format("cannot write {}: {} stamps for {} poses", file, stamps.size(), poses.size()));
  std::string text;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose& T = poses[i];
    if (format == PoseFormat::kKitti) {
      const Eigen::Matrix<double, 3, 4> M = T.matrix().topRows<3>();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) fmt::format_to(std::back_inserter(text), "{}{:.9e}", r + c == 0 ? "" : " ", M(r, c));
      text += '\n';
    } else {
      const Eigen::Quaterniond q(T.linear());
      const Vec3d t = T.translation();
      fmt::format_to(std::back_inserter(text), "{:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}\n", stamps[i],
                     t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    }
  }
  write_output_file(file, text);
}

}  // namespace slamvdb
