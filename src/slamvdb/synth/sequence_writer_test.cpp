#include "slamvdb/synth/sequence_writer.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"
#include "slamvdb/fusion/trajectory.hpp"
#include "slamvdb/synth/camera_sim.hpp"

namespace slamvdb::synth {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(fs::temp_directory_path() / fmt::format("slamvdb_synth_{}_{}", name, getpid())) {
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string file_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

template <typename T>
std::vector<T> read_array(const fs::path& p) {
  const std::string bytes = file_bytes(p);
  std::vector<T> out(bytes.size() / sizeof(T));
  std::memcpy(out.data(), bytes.data(), out.size() * sizeof(T));
  return out;
}

std::map<std::string, std::string> all_files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).string()] = file_bytes(e.path());
  return files;
}

std::vector<fs::path> sorted_files(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

// The files read back with nothing but their documented formats.
struct WrittenSequence {
  std::vector<double> scan_stamps;
  std::vector<Pose> poses;
  std::vector<fs::path> bins, labels, images, label_images;
  std::vector<int64_t> image_stamps_ms;
  CameraModel camera;
  Pose T_lidar_camera = Pose::Identity();

  explicit WrittenSequence(const fs::path& dir) {
    std::istringstream times(file_bytes(dir / "times.txt"));
    for (double t; times >> t;) scan_stamps.push_back(t);
    std::istringstream pose_text(file_bytes(dir / "poses.txt"));
    for (std::string line; std::getline(pose_text, line);) {
      std::istringstream row(line);
      Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) row >> M(r, c);
      Pose T = Pose::Identity();
      T.matrix() = M;
      poses.push_back(T);
    }
    bins = sorted_files(dir / kLidarDir);
    labels = sorted_files(dir / kLidarLabelDir);
    images = sorted_files(dir / kImageDir);
    label_images = sorted_files(dir / kImageLabelDir);
    static const std::regex kName(R"(frame(\d{6})-(\d+)_(\d{3}))");
    for (std::size_t k = 0; k < images.size(); ++k) {
      std::smatch m;
      const std::string stem = images[k].stem().string();
      EXPECT_TRUE(std::regex_match(stem, m, kName)) << stem;
      EXPECT_EQ(std::stoul(m[1]), k);
      image_stamps_ms.push_back(std::stoll(m[2]) * 1000 + std::stoll(m[3]));
      EXPECT_EQ(label_images[k].stem().string(), stem);
    }
    std::istringstream info(file_bytes(dir / "camera_info.txt"));
    info >> camera.fx >> camera.fy >> camera.cx >> camera.cy;
    for (double& k : camera.distortion) info >> k;
    const cv::Mat first = cv::imread(label_images.at(0).string(), cv::IMREAD_UNCHANGED);
    camera.width = first.cols;
    camera.height = first.rows;
    const YAML::Node yaml = YAML::LoadFile((dir / "transforms.yaml").string())["os1_cloud_node-pylon_camera_node"];
    const Eigen::Quaterniond q(yaml["q"]["w"].as<double>(), yaml["q"]["x"].as<double>(), yaml["q"]["y"].as<double>(),
                               yaml["q"]["z"].as<double>());
    T_lidar_camera.linear() = q.normalized().toRotationMatrix();
    T_lidar_camera.translation() =
        Vec3d(yaml["t"]["x"].as<double>(), yaml["t"]["y"].as<double>(), yaml["t"]["z"].as<double>());
  }
};

SynthConfig small_config(uint64_t seed) {
  SynthConfig config;
  config.seed = seed;
  config.length_m = 6.0;
  config.lidar.columns = 256;
  config.image_width = 160;
  config.image_height = 100;
  return config;
}

TEST(SynthSequence, SameSeedSameBytesWhateverTheThreadCountOtherSeedDiffers) {
  const TempDir a("det_a"), b("det_b"), c("det_c");
  {
    const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    write_synthetic_sequence(small_config(5), a.path());
  }
  {
    const tbb::global_control two_threads(tbb::global_control::max_allowed_parallelism, 2);
    write_synthetic_sequence(small_config(5), b.path());
  }
  write_synthetic_sequence(small_config(6), c.path());
  const auto files_a = all_files(a.path()), files_b = all_files(b.path()), files_c = all_files(c.path());
  ASSERT_GT(files_a.size(), 30u);
  EXPECT_TRUE(files_a == files_b) << "same seed, different bytes";
  std::size_t differing = 0;
  for (const auto& [name, bytes] : files_a)
    if (auto it = files_c.find(name); it == files_c.end() || it->second != bytes) ++differing;
  EXPECT_GT(differing, files_a.size() / 2) << "another seed must give another sequence";
}

TEST(SynthSequence, WritesTheRellisLayoutConsistently) {
  const TempDir dir("layout");
  const SynthSummary summary = write_synthetic_sequence(small_config(1), dir.path());
  const WrittenSequence seq(dir.path());
  ASSERT_EQ(seq.bins.size(), summary.scans);
  ASSERT_EQ(seq.labels.size(), summary.scans);
  ASSERT_EQ(seq.poses.size(), summary.scans);
  ASSERT_EQ(seq.scan_stamps.size(), summary.scans);
  ASSERT_EQ(seq.images.size(), summary.images);
  EXPECT_GE(summary.path_length_m, 6.0);
  EXPECT_NEAR(seq.scan_stamps.front(), 1700000000.0, 1e-6);
  EXPECT_EQ(seq.bins.front().filename(), "000000.bin");
  std::size_t points = 0;
  for (std::size_t i = 0; i < seq.bins.size(); ++i) {
    EXPECT_EQ(seq.bins[i].stem(), seq.labels[i].stem());
    const auto xyzi = read_array<float>(seq.bins[i]);
    const auto ids = read_array<uint32_t>(seq.labels[i]);
    ASSERT_EQ(xyzi.size(), 4 * ids.size());
    points += ids.size();
    for (uint32_t id : ids) ASSERT_TRUE(find_fine_class(static_cast<uint16_t>(id & 0xffff))) << id;
    for (std::size_t p = 0; p < ids.size(); ++p)
      ASSERT_GT(Eigen::Vector3f(xyzi[4 * p], xyzi[4 * p + 1], xyzi[4 * p + 2]).norm(), 0.5f);  // no zero points
    if (i > 0) {
      EXPECT_NEAR(seq.scan_stamps[i] - seq.scan_stamps[i - 1], 0.1, 1e-5);
    }
  }
  EXPECT_EQ(points, summary.points);
  for (std::size_t k = 0; k < seq.images.size(); ++k) {
    const cv::Mat rgb = cv::imread(seq.images[k].string(), cv::IMREAD_UNCHANGED);
    const cv::Mat labels = cv::imread(seq.label_images[k].string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(rgb.type(), CV_8UC3);
    EXPECT_EQ(labels.type(), CV_8UC1);
    EXPECT_EQ(rgb.size(), cv::Size(160, 100));
    EXPECT_EQ(labels.size(), cv::Size(160, 100));
  }
  EXPECT_NEAR(seq.camera.fx, 2813.643275 / 12.0, 1e-5);
  EXPECT_NEAR(seq.camera.distortion[0], -0.134313, 1e-12);
  EXPECT_TRUE(seq.T_lidar_camera.isApprox(rellis_T_lidar_camera(), 1e-7));
  const std::string yaml = file_bytes(dir.path() / "transforms.yaml");
  EXPECT_TRUE(yaml.starts_with("os1_cloud_node-pylon_camera_node:\n  q:\n    w: ")) << yaml;
  const auto meta = nlohmann::json::parse(file_bytes(dir.path() / "synth.json"));
  EXPECT_EQ(meta["simulated"], true);
  EXPECT_EQ(meta["seed"], 1);
  EXPECT_EQ(meta["counts"]["scans"], summary.scans);
  EXPECT_EQ(meta["parameters"]["lidar"]["columns"], 256);
  EXPECT_EQ(meta["classes"].size(), 17u);
  EXPECT_EQ(summary.bytes, [&] {
    std::uintmax_t total = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir.path()))
      if (e.is_regular_file()) total += e.file_size();
    return total;
  }());
}

// LiDAR points of a scan, moved to the camera's time with the interpolated ground-truth pose and
// projected through the written calibration, land on pixels of their own class. This checks the
// extrinsics, intrinsics, distortion and every time stamp together, from the files alone.
TEST(SynthSequence, LidarPointsProjectOntoTheirClassInTheCameraLabels) {
  const TempDir dir("consistency");
  SynthConfig config;
  config.length_m = 8.0;
  write_synthetic_sequence(config, dir.path());
  const WrittenSequence seq(dir.path());
  const Trajectory trajectory(seq.scan_stamps, seq.poses);
  const auto agreement = [&](bool invert_extrinsics) {
    std::size_t agree = 0, compared = 0;
    for (std::size_t k = 0; k < seq.images.size(); ++k) {
      const double tc = seq.image_stamps_ms[k] / 1000.0;
      const auto nearest = std::min_element(seq.scan_stamps.begin(), seq.scan_stamps.end(),
                                            [&](double a, double b) { return std::abs(a - tc) < std::abs(b - tc); });
      const std::size_t i = static_cast<std::size_t>(nearest - seq.scan_stamps.begin());
      EXPECT_NE(*nearest, tc);
      EXPECT_LT(std::abs(*nearest - tc), 0.06);
      const Pose T_lidar_now_scan = trajectory.at(tc)->inverse() * seq.poses[i];  // scan frame -> LiDAR at tc
      const Pose T_camera_lidar = invert_extrinsics ? seq.T_lidar_camera.inverse() : seq.T_lidar_camera;
      const Pose T_camera_scan = T_camera_lidar * T_lidar_now_scan;
      const auto xyzi = read_array<float>(seq.bins[i]);
      const cv::Mat labels = cv::imread(seq.label_images[k].string(), cv::IMREAD_UNCHANGED);
      const auto ids = read_array<uint32_t>(seq.labels[i]);
      for (std::size_t p = 0; p < ids.size(); ++p) {
        const Vec3d point(xyzi[4 * p], xyzi[4 * p + 1], xyzi[4 * p + 2]);
        const auto uv = seq.camera.project(T_camera_scan * point);
        if (!uv) continue;
        const long u = std::lround(uv->x()), v = std::lround(uv->y());
        if (u < 0 || v < 0 || u >= labels.cols || v >= labels.rows) continue;
        const uint8_t pixel = labels.at<uint8_t>(static_cast<int>(v), static_cast<int>(u));
        if (pixel == kSkyClass) continue;
        ++compared;
        agree += pixel == (ids[p] & 0xffff);
      }
    }
    EXPECT_GT(compared, 10000u);
    return static_cast<double>(agree) / std::max<std::size_t>(compared, 1);
  };
  EXPECT_GT(agreement(true), 0.85);
  EXPECT_LT(agreement(false), 0.5) << "the check must notice a wrong extrinsic convention";
}

TEST(SynthSequence, RefusesToOverwriteUnlessAskedThenLeavesNoStaleFiles) {
  const TempDir dir("overwrite");
  SynthConfig config = small_config(1);
  write_synthetic_sequence(config, dir.path());
  const std::size_t first_scans = sorted_files(dir.path() / kLidarDir).size();
  try {
    write_synthetic_sequence(config, dir.path());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  config.length_m = 3.0;
  config.keep_no_return = true;
  const SynthSummary s = write_synthetic_sequence(config, dir.path(), true);
  const auto bins = sorted_files(dir.path() / kLidarDir);
  EXPECT_LT(bins.size(), first_scans);
  EXPECT_EQ(bins.size(), s.scans);
  EXPECT_EQ(sorted_files(dir.path() / kImageDir).size(), s.images);
  // With --keep-no-return every scan holds the full 64 x 256 pattern, zeros included.
  std::size_t zeros = 0;
  for (const auto& bin : bins) {
    const auto xyzi = read_array<float>(bin);
    ASSERT_EQ(xyzi.size(), 4u * 64 * 256);
    for (std::size_t p = 0; p < xyzi.size() / 4; ++p)
      zeros += xyzi[4 * p] == 0.0f && xyzi[4 * p + 1] == 0.0f && xyzi[4 * p + 2] == 0.0f;
  }
  EXPECT_EQ(zeros, s.no_returns);
  EXPECT_GT(zeros, 0u);
}

TEST(SynthSequence, CommandLineWritesASimulatedSequenceAndGuardsItsOutput) {
  const TempDir dir("cli");
  const fs::path log = dir.path().string() + ".log";
  const std::string base =
      fmt::format("{} synth {} --length 2 --image-size 64x40 --seed 4", SLAMVDB_CLI_PATH, dir.path().string());
  ASSERT_EQ(std::system((base + " > " + log.string() + " 2>&1").c_str()), 0) << file_bytes(log);
  EXPECT_NE(file_bytes(log).find("SIMULATED"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir.path() / "synth.json"));
  EXPECT_EQ(cv::imread(sorted_files(dir.path() / kImageDir).at(0).string()).cols, 64);
  EXPECT_NE(std::system((base + " > " + log.string() + " 2>&1").c_str()), 0);
  EXPECT_NE(file_bytes(log).find("--force"), std::string::npos) << file_bytes(log);
  EXPECT_EQ(std::system((base + " --force > " + log.string() + " 2>&1").c_str()), 0) << file_bytes(log);
  const std::string bad_size =
      fmt::format("{} synth {} --force --image-size 64by40", SLAMVDB_CLI_PATH, dir.path().string());
  EXPECT_NE(std::system((bad_size + " > " + log.string() + " 2>&1").c_str()), 0);
  EXPECT_NE(file_bytes(log).find("WIDTHxHEIGHT"), std::string::npos) << file_bytes(log);
  fs::remove(log);
}

}  // namespace
}  // namespace slamvdb::synth
