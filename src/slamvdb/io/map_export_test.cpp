#include "slamvdb/io/map_export.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/QR>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

class MapExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("slamvdb_map_export_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

MapParams params_of(double voxel_size, int dim) {
  MapParams params;
  params.occupancy.voxel_size = voxel_size;
  params.semantic = {dim, EmbeddingPrecision::kFloat32};
  return params;
}

SemanticMap empty_map(double voxel_size, int dim) { return SemanticMap(params_of(voxel_size, dim)); }

TEST(MapExport, PcaRecoversTheAxesOfLargestVarianceAndMapsThemToChannels) {
  constexpr int dim = 16;
  SemanticMap map = empty_map(1.0, dim);
  VoxelMap voxels(map.params());
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  Eigen::MatrixXd random(dim, dim);
  for (Eigen::Index i = 0; i < random.size(); ++i) random(i) = g(rng);
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ();
  const Eigen::MatrixXf basis = q.cast<float>();
  const Eigen::VectorXf mean = Eigen::VectorXf::Constant(dim, 0.25f);
  auto embedding = [&](float a, float b, float c) -> Eigen::VectorXf {
    return mean + a * basis.col(0) + b * basis.col(1) + c * basis.col(2);
  };
  int x = 0;
  for (int i = -4; i <= 4; ++i)  // spreads 3 : 2 : 1 along the first three basis vectors
    for (int j = -4; j <= 4; ++j)
      for (int k = -4; k <= 4; ++k) {
        const Eigen::VectorXf e = embedding(0.75f * i, 0.5f * j, 0.25f * k);
        voxels.semantics().set({x++, 0, 0}, e.data(), 1);
      }
  map.add_finished_submap({}, std::move(voxels));
  const ColourBasis pca = fit_pca_colouring(map);
  for (int c = 0; c < 3; ++c) EXPECT_GT(std::abs(pca.components.row(c).dot(basis.col(c))), 0.999f) << c;
  EXPECT_LT((pca.mean - mean).norm(), 1e-5f);

  // Beyond the 98th percentile -> 255, below the 2nd -> 0, the centre -> mid-range.
  const float s0 = pca.components.row(0).dot(basis.col(0)) > 0 ? 1.0f : -1.0f;
  EXPECT_EQ(pca.colour(embedding(10.0f * s0, 0, 0).data())[0], 255);
  EXPECT_EQ(pca.colour(embedding(-10.0f * s0, 0, 0).data())[0], 0);
  for (const uint8_t v : pca.colour(mean.data())) EXPECT_NEAR(v, 128, 2);

  // Subsampling keeps the axes (an even stride over key order).
  const ColourBasis sub = fit_pca_colouring(map, 100);
  EXPECT_GT(std::abs(sub.components.row(0).dot(basis.col(0))), 0.99f);
  EXPECT_THROW(fit_pca_colouring(empty_map(1.0, 4)), Error);
}

TEST(MapExport, VoxelsArePlacedInTheWorldAndUnlabelledOnesGreyByHeight) {
  SemanticMap map = empty_map(1.0, 4);
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(10, 0, 0);
  VoxelMap voxels(map.params());
  OccupancyGrid& grid = voxels.occupancy();
  grid.set_log_odds({0, 0, 0}, 1.0f);
  grid.set_log_odds({0, 0, 5}, 1.0f);
  grid.set_log_odds({3, 0, 0}, 1.0f);
  grid.set_log_odds({4, 0, 0}, -1.0f);  // free: not exported
  const float e[4] = {1, 2, 3, 4};
  voxels.semantics().set({3, 0, 0}, e, 7);
  SubmapInfo info;
  info.T_world_submap = T;
  map.add_finished_submap(info, std::move(voxels));
  const auto coloured = colour_occupied_voxels(map, [](const float* v) {
    return Rgb{static_cast<uint8_t>(v[0]), static_cast<uint8_t>(v[1]), static_cast<uint8_t>(v[3])};
  });
  ASSERT_EQ(coloured.size(), 3u);
  auto at = [&](const Vec3f& p) {
    for (const ColouredVoxel& v : coloured)
      if ((v.position - p).norm() < 1e-5f) return v;
    ADD_FAILURE() << "no voxel at " << p.transpose();
    return ColouredVoxel{};
  };
  // Key centre (x, y) -> rotated by 90 degrees (-y, x) -> shifted by 10 in x.
  const ColouredVoxel semantic = at({9.5f, 3.5f, 0.5f});
  EXPECT_EQ(semantic.rgb, (Rgb{1, 2, 4}));
  EXPECT_EQ(semantic.count, 7u);
  const ColouredVoxel low = at({9.5f, 0.5f, 0.5f}), high = at({9.5f, 0.5f, 5.5f});
  EXPECT_EQ(low.count, 0u);
  EXPECT_EQ(low.rgb, (Rgb{60, 60, 60}));
  EXPECT_EQ(high.rgb, (Rgb{240, 240, 240}));
}

std::vector<ColouredVoxel> sample_voxels() {
  return {{{0.5f, 0.5f, 0.0f}, {255, 0, 0}, 1},
          {{0.5f, 0.5f, 2.0f}, {0, 255, 0}, 2},  // above the red one: the picture shows it
          {{3.5f, 1.5f, 1.0f}, {0, 0, 255}, 0},
          {{5.5f, 4.5f, -1.0f}, {200, 100, 50}, 4000000000u}};
}

using testing::read_text_file;

const char* const kPlyProperties =
    "element vertex 4\n"
    "property float x\nproperty float y\nproperty float z\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    "property int count\nend_header\n";

TEST_F(MapExportTest, BinaryPlyParsesBackExactly) {
  const auto voxels = sample_voxels();
  const fs::path path = dir_ / "map.ply";
  std::size_t last_done = 0;
  write_ply(path, voxels, PlyEncoding::kBinaryLittleEndian, [&](std::size_t done, std::size_t) { last_done = done; });
  EXPECT_EQ(last_done, voxels.size());
  const std::string bytes = read_text_file(path);
  ASSERT_TRUE(bytes.starts_with("ply\nformat binary_little_endian 1.0\n"));
  const std::size_t header_end = bytes.find("end_header\n") + std::strlen("end_header\n");
  EXPECT_NE(bytes.substr(0, header_end).find(kPlyProperties), std::string::npos);
  ASSERT_EQ(bytes.size(), header_end + voxels.size() * 19);
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const char* v = bytes.data() + header_end + 19 * i;
    float xyz[3];
    uint32_t count;
    std::memcpy(xyz, v, 12);
    std::memcpy(&count, v + 15, 4);
    EXPECT_EQ(Vec3f(xyz[0], xyz[1], xyz[2]), voxels[i].position);
    EXPECT_EQ((Rgb{uint8_t(v[12]), uint8_t(v[13]), uint8_t(v[14])}), voxels[i].rgb);
    EXPECT_EQ(count, std::min<uint32_t>(voxels[i].count, INT32_MAX));  // int32 (Open3D drops uint)
  }
}

TEST_F(MapExportTest, AsciiPlyParsesBackExactly) {
  auto voxels = sample_voxels();
  voxels[2].position = {0.1f, -1e-7f, 12345.678f};  // shortest round-trip text must restore the floats
  const fs::path path = dir_ / "map.ply";
  write_ply(path, voxels, PlyEncoding::kAscii);
  std::istringstream in(read_text_file(path));
  std::string line, header;
  while (std::getline(in, line) && line != "end_header") header += line + "\n";
  header += "end_header\n";
  EXPECT_TRUE(header.starts_with("ply\nformat ascii 1.0\n"));
  EXPECT_NE(header.find(kPlyProperties), std::string::npos);
  for (const ColouredVoxel& v : voxels) {
    ASSERT_TRUE(std::getline(in, line));
    std::istringstream fields(line);
    std::string x, y, z;
    unsigned r, g, b;
    uint32_t count;
    fields >> x >> y >> z >> r >> g >> b >> count;
    EXPECT_EQ(Vec3f(std::stof(x), std::stof(y), std::stof(z)), v.position) << line;
    EXPECT_EQ((Rgb{uint8_t(r), uint8_t(g), uint8_t(b)}), v.rgb);
    EXPECT_EQ(count, std::min<uint32_t>(v.count, INT32_MAX));
  }
  EXPECT_FALSE(std::getline(in, line));
}

cv::Vec3b rgb_at(const BirdsEyeImage& image, double x, double y) {
  const Eigen::Vector2i p = image.pixel_of(x, y);
  return image.rgb.at<cv::Vec3b>(p.y(), p.x());
}

TEST_F(MapExportTest, BirdsEyeShowsTheHighestVoxelOfEachColumn) {
  const auto voxels = sample_voxels();
  const BirdsEyeImage image = render_birds_eye(voxels, 1.0);  // automatic: one pixel per voxel
  EXPECT_EQ(image.resolution, 1.0);
  EXPECT_EQ(image.rgb.cols, 6);
  EXPECT_EQ(image.rgb.rows, 5);
  EXPECT_EQ(image.pixel_of(0.5, 0.5), Eigen::Vector2i(0, 4));  // y up: the bottom row
  EXPECT_EQ(rgb_at(image, 0.5, 0.5), cv::Vec3b(0, 255, 0));
  EXPECT_EQ(rgb_at(image, 3.5, 1.5), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(rgb_at(image, 5.5, 4.5), cv::Vec3b(200, 100, 50));
  EXPECT_EQ(rgb_at(image, 1.5, 1.5), cv::Vec3b(0, 0, 0));  // background
  EXPECT_EQ(cv::countNonZero(image.rgb.reshape(1)), 5);  // non-zero channels: green 1, blue 1, last voxel 3

  // What is written is what was rendered (RGB kept through OpenCV's BGR).
  const fs::path png = dir_ / "map.png";
  write_png(png, image);
  cv::Mat bgr = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(bgr.empty());
  EXPECT_EQ(bgr.at<cv::Vec3b>(3, 3), cv::Vec3b(255, 0, 0));  // the blue voxel at (3.5, 1.5)
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 5), cv::Vec3b(50, 100, 200));
  EXPECT_THROW(write_png(dir_ / "map.jpg", image), Error);
  EXPECT_THROW(write_png(dir_ / "no_such_dir" / "map.png", image), Error);

  // Pixels finer than voxels: each voxel fills its footprint.
  BirdsEyeParams fine;
  fine.resolution = 0.25;
  const BirdsEyeImage zoomed = render_birds_eye(voxels, 1.0, fine);
  EXPECT_EQ(zoomed.rgb.cols, 24);
  EXPECT_EQ(rgb_at(zoomed, 0.1, 0.9), cv::Vec3b(0, 255, 0));
  EXPECT_EQ(rgb_at(zoomed, 0.9, 0.1), cv::Vec3b(0, 255, 0));
  EXPECT_EQ(rgb_at(zoomed, 1.1, 0.5), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(cv::countNonZero(zoomed.rgb.reshape(1)), 5 * 16);
}

TEST_F(MapExportTest, BirdsEyeResolutionIsCappedAndChecked) {
  const std::vector<ColouredVoxel> wide = {{{0.125f, 0.125f, 0.0f}, {9, 9, 9}, 0},
                                           {{999.875f, 0.125f, 0.0f}, {9, 9, 9}, 0}};
  const BirdsEyeImage image = render_birds_eye(wide, 0.25);
  EXPECT_EQ(image.resolution, 0.5);  // 1000 m in at most 2000 px
  EXPECT_EQ(image.rgb.cols, 2000);
  BirdsEyeParams too_fine;
  too_fine.resolution = 0.01;
  EXPECT_THROW(render_birds_eye(wide, 0.25, too_fine), Error);
  EXPECT_THROW(render_birds_eye({}, 0.25), Error);
}

TEST_F(MapExportTest, HillShadingLightsSlopesFacingNorthWest) {
  // A ridge along y: its west flank faces the light, its east flank faces away, the top is flat.
  std::vector<ColouredVoxel> voxels;
  for (int x = 0; x < 21; ++x)
    for (int y = 0; y < 5; ++y) {
      const float z = static_cast<float>(10 - std::abs(x - 10));
      voxels.push_back({{x + 0.5f, y + 0.5f, z}, {100, 100, 100}, 0});
    }
  BirdsEyeParams params;
  params.hill_shading = true;
  const BirdsEyeImage image = render_birds_eye(voxels, 1.0, params);
  const int west = rgb_at(image, 5.5, 2.5)[0], east = rgb_at(image, 15.5, 2.5)[0];
  EXPECT_GT(west, 100);
  EXPECT_LT(east, 100);
  params.hill_shading = false;
  EXPECT_EQ(rgb_at(render_birds_eye(voxels, 1.0, params), 5.5, 2.5), cv::Vec3b(100, 100, 100));
}

// ---- the CLI commands `info` and `export` on a saved map ----

struct CliRun {
  int exit_code;
  std::string output;  // stdout and stderr
};

CliRun run_cli(const std::string& args) {
  const std::string command = std::string("'") + SLAMVDB_CLI_PATH + "' " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::string output;
  char buffer[4096];
  while (const std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) output.append(buffer, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

using testing::quote_path;

SemanticMap small_semantic_map() {
  MapParams params;
  params.semantic = {16, EmbeddingPrecision::kFloat16};
  SemanticMap map(params,
                  {.model_id = "simulated-clip-16", .ontology = "rellis3d", .source = "SIMULATED CLI test map"});
  Pose T = Pose::Identity();
  T.translation() = Vec3d(20, -5, 1);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(-1, 1);
  float e[16];
  for (int id : {0, 1}) {
    VoxelMap s(params);
    for (int x = 0; x < 30; ++x)
      for (int y = 0; y < 20; ++y) {
        s.occupancy().set_log_odds({x, y, x / 10}, 2.0f);
        s.occupancy().set_log_odds({x, y, x / 10 + 1}, -1.0f);
        if (y % 2) continue;
        for (float& v : e) v = unit(rng);
        s.semantics().set({x, y, x / 10}, e, 1 + x);
      }
    SubmapInfo info;
    info.id = id;
    info.T_world_submap = id ? T : Pose::Identity();
    map.add_finished_submap(info, std::move(s));
  }
  return map;
}

std::size_t ply_vertex_count(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::string line;
  while (std::getline(in, line) && line != "end_header")
    if (line.starts_with("element vertex ")) return std::stoul(line.substr(15));
  return 0;
}

TEST_F(MapExportTest, CliInfoPrintsCountsAndExportWritesBothFiles) {
  const SemanticMap map = small_semantic_map();
  const fs::path path = dir_ / "map.svdb";
  save_map(path, map);

  const CliRun json = run_cli("info " + quote_path(path) + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.output;
  const auto j = nlohmann::json::parse(json.output);
  EXPECT_EQ(j["voxels"]["known"], map.num_known_voxels());
  EXPECT_EQ(j["voxels"]["occupied"], map.num_occupied_voxels());
  EXPECT_EQ(j["voxels"]["semantic"], map.num_semantic_voxels());
  EXPECT_EQ(j["bytes"]["file"], fs::file_size(path));
  EXPECT_EQ(j["precision"], "fp16");
  EXPECT_EQ(j["embedding_dim"], 16);
  EXPECT_EQ(j["model_id"], "simulated-clip-16");
  ASSERT_EQ(j["submaps"].size(), 2u);
  EXPECT_EQ(j["submaps"][1]["translation"][0], 20.0);

  const CliRun text = run_cli("info " + quote_path(path));
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_NE(text.output.find(fmt::format("{} known, {} occupied", map.num_known_voxels(), map.num_occupied_voxels())),
            std::string::npos)
      << text.output;
  EXPECT_NE(text.output.find(fmt::format("{} semantic voxels, 16-d fp16", map.num_semantic_voxels())),
            std::string::npos)
      << text.output;
  EXPECT_NE(text.output.find("SIMULATED CLI test map"), std::string::npos) << text.output;

  const fs::path ply = dir_ / "out.ply", png = dir_ / "out.png";
  const CliRun exported = run_cli("export " + quote_path(path) + " --ply " + quote_path(ply) + " --png " + quote_path(png));
  ASSERT_EQ(exported.exit_code, 0) << exported.output;
  EXPECT_EQ(ply_vertex_count(ply), map.num_occupied_voxels());
  EXPECT_TRUE(read_text_file(ply).starts_with("ply\nformat binary_little_endian"));
  const cv::Mat picture = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(picture.empty());
  // x from 0 to 27.5 m (second submap shifted by 20 m), y from -5 to 5 m, at 0.25 m per pixel: 110 x 40,
  // enlarged by a whole factor for the legend (the YAML beside it gives the resolution).
  ASSERT_EQ(picture.cols % 110, 0);
  const int k = picture.cols / 110;
  EXPECT_EQ(picture.rows, 40 * k);
  EXPECT_NE(read_text_file(dir_ / "out.yaml").find(fmt::format("resolution: {:.6f}", 0.25 / k)), std::string::npos);
  EXPECT_GT(cv::countNonZero(picture.reshape(1)), 0);

  const CliRun ascii = run_cli("export " + quote_path(path) + " --ascii --ply " + quote_path(ply));
  ASSERT_EQ(ascii.exit_code, 0) << ascii.output;
  EXPECT_TRUE(read_text_file(ply).starts_with("ply\nformat ascii 1.0\n"));
}

TEST_F(MapExportTest, CliFailsClearlyOnCorruptMapsAndBadArguments) {
  const fs::path path = dir_ / "map.svdb";
  save_map(path, small_semantic_map());
  std::string bytes = read_text_file(path);
  bytes.resize(bytes.size() / 2);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;

  for (const std::string& args : {"info " + quote_path(path), "export " + quote_path(path) + " --ply " + quote_path(dir_ / "o.ply")}) {
    const CliRun run = run_cli(args);
    EXPECT_NE(run.exit_code, 0) << args;
    EXPECT_NE(run.output.find(path.string()), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("damaged or truncated"), std::string::npos) << run.output;
  }
  EXPECT_FALSE(fs::exists(dir_ / "o.ply"));

  const CliRun nothing = run_cli("export " + quote_path(path));
  EXPECT_NE(nothing.exit_code, 0);
  EXPECT_NE(nothing.output.find("nothing to export"), std::string::npos) << nothing.output;
  const CliRun no_dir = run_cli("export " + quote_path(path) + " --png " + quote_path(dir_ / "missing" / "o.png"));
  EXPECT_NE(no_dir.exit_code, 0);
  EXPECT_NE(no_dir.output.find("does not exist"), std::string::npos) << no_dir.output;
  const CliRun missing = run_cli("info " + quote_path(dir_ / "nope.svdb"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("no such file"), std::string::npos) << missing.output;
}

}  // namespace
}  // namespace slamvdb
