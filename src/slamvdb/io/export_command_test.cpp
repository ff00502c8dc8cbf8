// `slamvdb export` and `slamvdb classify` outputs as other tools read them: the format follows the
// extension (an unknown one is a usage error before any work), exports are byte-identical across
// runs, the PCD reads back, the PNG + YAML place a voxel at its world position, the CSV has one
// row per semantic cell, the navigation grid is written as PGM + YAML + PNG.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/io/pcd.hpp"
#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/two_class_map.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::run_command;
using testing::shell_quote;

using Fixture = testing::TwoClassMap;

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(ExportCommand, FormatsByExtensionDeterministicAndReadable) {
  Fixture f;
  const std::string map = shell_quote(f.map.string());
  const auto r = run_command(f.cli("export " + map + " -o " + f.out("a.ply") + " -o " + f.out("a.pcd") + " -o " +
                                   f.out("a.png") + " -o " + f.out("a.csv") + " -o " + f.out("a.npy") +
                                   " --queries " + shell_quote(f.queries.string())));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Twice the same bytes.
  ASSERT_EQ(run_command(f.cli("export " + map + " -o " + f.out("b.ply") + " -o " + f.out("b.pcd") + " --queries " +
                              shell_quote(f.queries.string())))
                .exit_code,
            0);
  EXPECT_EQ(read_all(f.tmp.path / "a.ply"), read_all(f.tmp.path / "b.ply"));
  EXPECT_EQ(read_all(f.tmp.path / "a.pcd"), read_all(f.tmp.path / "b.pcd"));
  EXPECT_NE(read_all(f.tmp.path / "a.ply").find("property int count"), std::string::npos);
  // The PCD reads back (our reader; PCL's layout).
  const PcdCloud cloud = read_pcd(f.tmp.path / "a.pcd");
  EXPECT_GT(cloud.points.size(), 900u);
  // CSV: one row per semantic cell, the documented header, classes by side.
  std::ifstream csv(f.tmp.path / "a.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "x,y,z,class,score,margin,count,confidence");
  std::size_t rows = 0, correct = 0;
  while (std::getline(csv, line)) {
    ++rows;
    const double x = std::stod(line.substr(0, line.find(',')));
    correct += line.find(x < 0 ? ",smooth," : ",rough,") != std::string::npos;
  }
  EXPECT_EQ(rows, f.semantic_cells);
  EXPECT_EQ(correct, rows);
  // PNG + YAML: the map_server origin and resolution place world points on their pixels.
  const YAML::Node yaml = YAML::LoadFile((f.tmp.path / "a.yaml").string());
  const cv::Mat png = cv::imread((f.tmp.path / "a.png").string());
  const double res = yaml["resolution"].as<double>(), ox = yaml["origin"][0].as<double>(),
               oy = yaml["origin"][1].as<double>();
  const auto bgr_at = [&](double x, double y) {
    return png.at<cv::Vec3b>(png.rows - 1 - static_cast<int>((y - oy) / res), static_cast<int>((x - ox) / res));
  };
  EXPECT_NE(bgr_at(-1.0, -2.0), bgr_at(1.0, -2.0));  // the two classes' colours, at their world positions
  EXPECT_EQ(bgr_at(-1.0, -2.0), bgr_at(-1.6, -2.2));
  EXPECT_EQ(bgr_at(1.0, -2.0), bgr_at(2.2, -1.7));
  EXPECT_GE(png.cols, 8 * 32);  // a small map (32 px) is enlarged for its legend
  EXPECT_TRUE(fs::exists(f.tmp.path / "a.positions.npy"));
  EXPECT_TRUE(fs::exists(f.tmp.path / "a.counts.npy"));
}

TEST(ExportCommand, UnknownFormatsAreUsageErrorsBeforeWork) {
  Fixture f;
  const std::string map = shell_quote(f.map.string());
  EXPECT_EQ(run_command(f.cli("export " + map + " -o " + f.out("x.pgm"))).exit_code, 2);
  EXPECT_EQ(run_command(f.cli("export " + map + " --ply " + f.out("x.pcd"))).exit_code, 2);
  EXPECT_EQ(run_command(f.cli("export " + map)).exit_code, 2);
  EXPECT_EQ(run_command(f.cli("export " + map + " -o /no/such/dir/x.ply")).exit_code, 2);
  EXPECT_EQ(run_command(f.cli("query " + map + " --text grass -o " + f.out("x.pcd"))).exit_code, 2);
  EXPECT_EQ(run_command(f.cli("export " + map + " -o " + f.out("x.bin") + " --format ply")).exit_code, 0);
  EXPECT_FALSE(fs::exists(f.tmp.path / "x.pgm"));
}

TEST(ExportCommand, ClassifyWritesTerrainPictureAndNavigationGrid) {
  Fixture f;
  const auto r = run_command(f.cli("classify " + shell_quote(f.map.string()) + " --queries " +
                                   shell_quote(f.queries.string()) + " --png " + f.out("t.png") + " --grid " +
                                   f.out("nav") + " --cost rough=40"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const YAML::Node yaml = YAML::LoadFile((f.tmp.path / "nav.yaml").string());
  EXPECT_EQ(yaml["mode"].as<std::string>(), "raw");
  const cv::Mat pgm = cv::imread((f.tmp.path / "nav.pgm").string(), cv::IMREAD_UNCHANGED);
  const double res = yaml["resolution"].as<double>(), ox = yaml["origin"][0].as<double>(),
               oy = yaml["origin"][1].as<double>();
  const auto cost_at = [&](double x, double y) {
    return int{pgm.at<uint8_t>(pgm.rows - 1 - static_cast<int>((y - oy) / res), static_cast<int>((x - ox) / res))};
  };
  EXPECT_EQ(cost_at(-1.0, 1.0), 0);   // smooth
  EXPECT_EQ(cost_at(1.0, 1.0), 40);   // rough, at the cost given
  EXPECT_TRUE(fs::exists(f.tmp.path / "nav.png"));
  EXPECT_TRUE(fs::exists(f.tmp.path / "t.yaml"));
  // A class without a default cost must be given one.
  EXPECT_EQ(run_command(f.cli("classify " + shell_quote(f.map.string()) + " --queries " +
                              shell_quote(f.queries.string()) + " --grid " + f.out("n2") + " --cost nosuch=3"))
                .exit_code,
            2);
}

TEST(ExportCommand, ClassifyMarksVoxelsBelowTheConfidenceThresholdUncertain) {
  Fixture f;
  const std::string base = "classify " + shell_quote(f.map.string()) + " --queries " + shell_quote(f.queries.string());
  // Rows named `uncertain`, and the confidences, of `classify -o` at threshold T.
  const auto run_at = [&](double t, std::vector<double>* confidences = nullptr) {
    const auto r = run_command(f.cli(base + " -o " + f.out("u.csv") + " --min-confidence " + std::to_string(t)));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::ifstream csv(f.tmp.path / "u.csv");
    std::string line;
    std::getline(csv, line);
    EXPECT_EQ(line, "x,y,z,class,score,margin,count,confidence,last_session");
    std::size_t uncertain = 0;
    while (std::getline(csv, line)) {
      uncertain += line.find(",uncertain,") != std::string::npos;
      const std::string fields = line.substr(0, line.rfind(','));  // without last_session
      if (confidences) confidences->push_back(std::stod(fields.substr(fields.rfind(',') + 1)));
    }
    return uncertain;
  };
  std::vector<double> confidences;
  EXPECT_EQ(run_at(0.0, &confidences), 0u);
  ASSERT_EQ(confidences.size(), f.semantic_cells);
  std::sort(confidences.begin(), confidences.end());
  ASSERT_GT(confidences.front(), 0.0);
  const std::size_t least = run_at(confidences.front() + 2e-4);  // above the least sure (CSV: 4 decimals)
  EXPECT_GT(least, 0u);
  EXPECT_LE(least, static_cast<std::size_t>(std::count_if(confidences.begin(), confidences.end(),
                                                          [&](double c) { return c <= confidences.front() + 3e-4; })));
  EXPECT_EQ(run_at(1.0), f.semantic_cells);  // n / (n + 2) < 1: nothing is that sure
  // Uncertain ground is unknown to the planner.
  ASSERT_EQ(run_command(f.cli(base + " --grid " + f.out("nav") + " --min-confidence 1")).exit_code, 0);
  const cv::Mat pgm = cv::imread((f.tmp.path / "nav.pgm").string(), cv::IMREAD_UNCHANGED);
  std::size_t passable = 0;
  for (int r = 0; r < pgm.rows; ++r)
    for (int c = 0; c < pgm.cols; ++c) passable += pgm.at<uint8_t>(r, c) < 100;
  EXPECT_EQ(passable, 0u);
  EXPECT_EQ(run_command(f.cli(base + " --min-confidence 1.5")).exit_code, 2);
}

}  // namespace
}  // namespace slamvdb
