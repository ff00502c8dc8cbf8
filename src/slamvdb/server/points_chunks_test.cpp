// collect_point_chunks in process: a loop correction (a new T_world_submap) moves a submap's chunks
// as a whole: the same chunks, the same quantised positions, only the pose differs, and the
// positions it gives are the moved voxel centres. Level-of-detail and budget rules.
#include "slamvdb/server/points_chunks.hpp"

#include <gtest/gtest.h>

#include "slamvdb/testing/two_class_map.hpp"

namespace slamvdb {
namespace {

std::vector<Vec3d> chunk_world_points(const PointChunks& chunks) {
  std::vector<Vec3d> points;
  for (const PointChunk& c : chunks.chunks)
    for (std::size_t i = 0; i < c.values.size(); ++i) {
      const Vec3f q(c.positions[3 * i], c.positions[3 * i + 1], c.positions[3 * i + 2]);
      points.push_back(c.T_world_submap * (c.origin_submap + c.step * q).cast<double>());
    }
  return points;
}

TEST(PointChunks, ALoopCorrectionMovesChunksWithoutRetiling) {
  testing::TwoClassMap f;
  SemanticMap map = load_map(f.map);
  const QuerySet queries = load_query_set(f.queries);
  PointValueSource source;
  source.queries = &queries;
  source.model_check = ModelIdCheck::kIgnore;
  const PointChunks before = collect_point_chunks(map, {}, source);
  ASSERT_FALSE(before.chunks.empty());
  EXPECT_EQ(before.values, PointChunks::Values::kClass);
  EXPECT_EQ(before.points, map.num_occupied_voxels());

  const int id = map.submaps().at(0).id;
  Pose corrected = Pose::Identity();
  corrected.linear() = Eigen::AngleAxisd(0.3, Vec3d::UnitZ()).toRotationMatrix();
  corrected.translation() = Vec3d(5.0, -2.0, 0.4);
  map.set_submap_poses({{id, corrected}});
  const PointChunks after = collect_point_chunks(map, {}, source);
  ASSERT_EQ(after.chunks.size(), before.chunks.size());
  for (std::size_t c = 0; c < after.chunks.size(); ++c) {
    EXPECT_EQ(after.chunks[c].positions, before.chunks[c].positions);
    EXPECT_EQ(after.chunks[c].origin_submap, before.chunks[c].origin_submap);
    EXPECT_TRUE(after.chunks[c].T_world_submap.isApprox(corrected));
  }
  // The decoded points are the moved voxel centres.
  std::vector<Vec3d> expected;
  map.read_submap(id, [&](const Submap& s) {
    s.voxels().occupancy().for_each_occupied(
        [&](const VoxelKey& k, float) { expected.push_back(corrected * s.voxels().occupancy().center_of(k)); });
  });
  const std::vector<Vec3d> got = chunk_world_points(after);
  ASSERT_EQ(got.size(), expected.size());
  for (const Vec3d& p : expected) {
    const auto near = std::find_if(got.begin(), got.end(), [&](const Vec3d& g) { return (g - p).norm() < 1e-4; });
    EXPECT_NE(near, got.end()) << p.transpose();
  }
}

TEST(PointChunks, LevelsOfDetailAndBudget) {
  testing::TwoClassMap f;
  const SemanticMap map = load_map(f.map);
  PointsRequest request;
  std::size_t previous = map.num_occupied_voxels();
  std::vector<std::size_t> points;
  for (int lod = 0; lod <= kPointsMaxLod; ++lod) {  // each level at most as many points as the finer one
    request.lod = lod;
    const PointChunks chunks = collect_point_chunks(map, request, {});
    EXPECT_LE(chunks.points, previous) << lod;
    previous = chunks.points;
    points.push_back(chunks.points);
    for (const PointChunk& c : chunks.chunks)
      for (const uint8_t v : c.values) EXPECT_EQ(v, kPointNoValue);  // no query set, no question
  }
  EXPECT_EQ(points[0], map.num_occupied_voxels());
  EXPECT_LT(points[2], points[0] / 8);
  request.lod = 0;
  request.limit = 5;
  EXPECT_THROW(collect_point_chunks(map, request, {}), PointsOverBudget);
  request.lod = kPointsMaxLod + 1;
  EXPECT_THROW(collect_point_chunks(map, request, {}), Error);
}

}  // namespace
}  // namespace slamvdb
