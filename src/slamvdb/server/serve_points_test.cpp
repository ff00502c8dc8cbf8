// GET /api/points against a real `slamvdb serve` on a loopback port: the bytes are decoded here by
// the layout of docs/openapi.yaml (independently of the encoder), the positions are the map's
// occupied voxel centres (within the quantum), the classes are `slamvdb classify`'s for the same
// cells, the scores of ?query= are `slamvdb query --text`'s, and refusals name the parameter.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <nlohmann/json.hpp>

#include "slamvdb/core/point_text.hpp"
#include "slamvdb/query/query_region.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

// One point of an answer: world position (T_world_submap * (origin + step * q)), its byte, its quantum.
struct DecodedPoint {
  Vec3d world;
  int value;
  double step;
};

struct DecodedPoints {
  nlohmann::json meta;
  int flags = 0;
  std::vector<DecodedPoint> points;
  std::size_t chunks = 0;
};

template <class T>
T read_le(const std::string& b, std::size_t& at) {
  EXPECT_LE(at + sizeof(T), b.size());
  T v{};
  if (at + sizeof(T) <= b.size()) std::memcpy(&v, b.data() + at, sizeof(T));
  at += sizeof(T);
  return v;
}

DecodedPoints decode_points(const std::string& b) {
  DecodedPoints d;
  EXPECT_EQ(b.substr(0, 4), "SVPT");
  std::size_t at = 4;
  EXPECT_EQ(read_le<uint16_t>(b, at), 1);  // version
  d.flags = read_le<uint16_t>(b, at);
  d.chunks = read_le<uint32_t>(b, at);
  const uint32_t meta_length = read_le<uint32_t>(b, at);
  EXPECT_EQ(meta_length % 4, 0u);
  d.meta = nlohmann::json::parse(b.substr(at, meta_length));
  at += meta_length;
  for (std::size_t c = 0; c < d.chunks && at < b.size(); ++c) {
    EXPECT_EQ(at % 4, 0u);
    read_le<int32_t>(b, at);  // submap id
    at += 4;                  // lod, padding
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 4; ++col) T(r, col) = read_le<float>(b, at);
    Vec3d origin;
    for (int a = 0; a < 3; ++a) origin[a] = read_le<float>(b, at);
    const double step = read_le<float>(b, at);
    const uint32_t n = read_le<uint32_t>(b, at);
    const std::size_t values_at = at + 6 * std::size_t{n};
    for (uint32_t i = 0; i < n; ++i) {
      Vec3d q;
      for (int a = 0; a < 3; ++a) q[a] = read_le<uint16_t>(b, at);
      const Vec3d p = origin + step * q;
      d.points.push_back({(T * p.homogeneous()).head<3>(), static_cast<unsigned char>(b.at(values_at + i)), step});
    }
    at = values_at + n;
    at = (at + 3) / 4 * 4;
  }
  EXPECT_EQ(at, b.size());
  return d;
}

// "x,y,z" at millimetres: how a cell is named in the CLI's CSV files.
std::string position_key(const Vec3d& p) { return fmt::format("{:.3f},{:.3f},{:.3f}", p.x(), p.y(), p.z()); }

// The occupied voxel centres of every submap of the map file, world frame, sorted.
std::vector<Vec3d> map_occupied_centres(const std::filesystem::path& file, const std::optional<QueryRegion>& region = {}) {
  const SemanticMap map = load_map(file);
  std::vector<Vec3d> centres;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      s.voxels().occupancy().for_each_occupied([&](const VoxelKey& k, float) {
        const Vec3d c = s.T_world_submap() * s.voxels().occupancy().center_of(k);
        if (!region || region->contains(c)) centres.push_back(c);
      });
    });
  return centres;
}

bool position_less(const Vec3d& a, const Vec3d& b) {
  return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

// The decoded positions equal `expected` one for one, each within its chunk's quantum.
void expect_same_positions(std::vector<DecodedPoint> got, std::vector<Vec3d> expected) {
  ASSERT_EQ(got.size(), expected.size());
  std::sort(got.begin(), got.end(), [](const auto& a, const auto& b) { return position_less(a.world, b.world); });
  std::sort(expected.begin(), expected.end(), position_less);
  for (std::size_t i = 0; i < got.size(); ++i)
    ASSERT_LE((got[i].world - expected[i]).cwiseAbs().maxCoeff(), got[i].step) << i << ": " << got[i].world.transpose()
                                                                              << " vs " << expected[i].transpose();
}

// CSV rows of the CLI keyed by position_key of columns x, y, z at `x_column`.
std::map<std::string, std::vector<std::string>> cli_rows_by_position(const std::string& csv, std::size_t x_column) {
  std::string error;
  const auto records = testing::read_csv_strict(csv, &error);
  EXPECT_TRUE(records) << error;
  std::map<std::string, std::vector<std::string>> rows;
  if (!records) return rows;
  for (std::size_t i = 1; i < records->size(); ++i) {
    const auto& r = (*records)[i];
    rows[position_key({std::stod(r[x_column]), std::stod(r[x_column + 1]), std::stod(r[x_column + 2])})] = r;
  }
  return rows;
}

httplib::Result get_points_answer(testing::ServedMap& s, const std::string& path) {
  auto res = s.client.Get(path);
  EXPECT_TRUE(res) << "no answer; server log:\n" << s.log();
  return res;
}

TEST(ServePoints, ChunksHoldTheOccupiedVoxelsWithClassifysClasses) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto res = get_points_answer(s, "/api/points");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/octet-stream");
  const DecodedPoints d = decode_points(res->body);
  EXPECT_EQ(d.flags, 0);
  EXPECT_EQ(d.meta.at("values"), "class");
  EXPECT_EQ(d.meta.at("points").get<std::size_t>(), d.points.size());
  EXPECT_EQ(d.meta.at("classes").size(), 2u);
  expect_same_positions(d.points, map_occupied_centres(s.f.map));

  // Every point's class is the one `classify -o X.csv` gives its cell; points without one have none.
  const auto out = s.f.tmp.path / "classes.csv";
  const auto r = run_command(s.f.cli("classify " + shell_quote(s.f.map.string()) + " --queries " +
                                     shell_quote(s.f.queries.string()) + " --ignore-model-id -o " + shell_quote(out.string())));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = cli_rows_by_position(testing::read_text_file(out), 0);
  ASSERT_GT(rows.size(), 100u);
  std::size_t classified = 0;
  for (const DecodedPoint& p : d.points) {
    const auto row = rows.find(position_key(p.world));
    if (row == rows.end() || row->second[3].empty()) {
      EXPECT_EQ(p.value, 255) << p.world.transpose();
      continue;
    }
    ASSERT_LT(p.value, 2) << p.world.transpose();
    EXPECT_EQ(d.meta["classes"][p.value]["name"], row->second[3]) << p.world.transpose();
    ++classified;
  }
  EXPECT_EQ(classified, rows.size());  // every classified cell is a point
}

TEST(ServePoints, BoxAndLevelOfDetail) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const std::string bbox = "-1.1,-0.9,-1,1.3,1.05,1";
  const auto res = get_points_answer(s, "/api/points?bbox=" + bbox);
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const DecodedPoints d = decode_points(res->body);
  const std::vector<double> box = parse_numbers(bbox, "bbox", 6, 6, "box");
  const QueryRegion region = make_region(std::span<const double>(box), {}, {});
  const auto inside = map_occupied_centres(s.f.map, region);
  ASSERT_GT(inside.size(), 10u);
  EXPECT_LT(inside.size(), map_occupied_centres(s.f.map).size());
  expect_same_positions(d.points, inside);
  EXPECT_EQ(d.meta.at("region").at("bbox").size(), 6u);

  // lod 2: one point per occupied 4 x 4 x 4 block of voxels, at its centre, fewer points.
  const auto coarse = get_points_answer(s, "/api/points?lod=2");
  ASSERT_TRUE(coarse);
  ASSERT_EQ(coarse->status, 200) << coarse->body;
  const DecodedPoints c = decode_points(coarse->body);
  const double block = 4 * 0.25;
  std::vector<Vec3d> blocks;
  for (const Vec3d& v : map_occupied_centres(s.f.map)) {
    const Vec3d centre = ((v / block).array().floor() + 0.5).matrix() * block;
    if (std::find(blocks.begin(), blocks.end(), centre) == blocks.end()) blocks.push_back(centre);
  }
  EXPECT_EQ(c.meta.at("lod"), 2);
  expect_same_positions(c.points, blocks);
}

TEST(ServePoints, QueryScoresAreTheClisScores) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto res = get_points_answer(s, "/api/points?query=grass");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const DecodedPoints d = decode_points(res->body);
  EXPECT_EQ(d.flags, 1);
  EXPECT_EQ(d.meta.at("values"), "score");
  const double lo = d.meta.at("score").at("lo"), hi = d.meta.at("score").at("hi");
  ASSERT_LT(lo, hi);
  const auto out = s.f.tmp.path / "scores.csv";
  const auto r = run_command(s.f.cli("query " + shell_quote(s.f.map.string()) +
                                     " --text grass --top-k 0 --threshold -1 --ignore-model-id -o " +
                                     shell_quote(out.string())));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = cli_rows_by_position(testing::read_text_file(out), 1);  // rank,x,y,z,score,...
  ASSERT_GT(rows.size(), 100u);
  std::size_t scored = 0;
  for (const DecodedPoint& p : d.points) {
    const auto row = rows.find(position_key(p.world));
    if (row == rows.end()) {
      EXPECT_EQ(p.value, 255);
      continue;
    }
    ASSERT_LE(p.value, 254);
    const double score = lo + (hi - lo) * p.value / 254.0;
    EXPECT_NEAR(score, std::stod(row->second[4]), (hi - lo) / 254.0 / 2 + 1e-6) << p.world.transpose();
    ++scored;
  }
  EXPECT_EQ(scored, rows.size());
}

TEST(ServePoints, RefusalsNameTheParameter) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto expect_error = [&](const std::string& query, int status, const std::string& field) {
    const auto res = get_points_answer(s, "/api/points?" + query);
    if (!res) return;
    EXPECT_EQ(res->status, status) << query << "\n" << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json") << query;
    const auto body = nlohmann::json::parse(res->body);
    EXPECT_EQ(body.at("error").at("field"), field) << query << "\n" << res->body;
  };
  expect_error("bbox=1,2,3", 400, "bbox");
  expect_error("bbox=1,1,1,0,0,0", 400, "bbox");
  expect_error("near=0,0", 400, "radius");
  expect_error("lod=9", 400, "lod");
  expect_error("lod=1.5", 400, "lod");
  expect_error("lod=x", 400, "lod");
  expect_error("limit=0", 400, "limit");
  expect_error("query=", 400, "query");
  expect_error("colour=red", 400, "colour");
  expect_error("limit=10", 413, "limit");  // the map holds ~1000 points at lod 0
  // The point budget is per level: a coarse level of the same map fits.
  const auto coarse = get_points_answer(s, "/api/points?lod=4&limit=10");
  ASSERT_TRUE(coarse);
  EXPECT_EQ(coarse->status, 200) << coarse->body;
}

}  // namespace
}  // namespace slamvdb
