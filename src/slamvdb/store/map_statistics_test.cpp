// Format 3 stores each semantic voxel's observation statistics (weight sum and spread, 8 bytes)
// beside its embedding; a format-2 file (no statistics columns) still loads, its statistics
// unknown (weight = count, spread NaN).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <map>
#include <tuple>

#include "slamvdb/query/class_confidence.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using namespace slamvdb::testing;

// Every semantic voxel of submap `id` as key -> statistics.
std::map<std::tuple<int, int, int>, VoxelStatistics> stored_statistics_by_key(const SemanticMap& map, int id) {
  std::map<std::tuple<int, int, int>, VoxelStatistics> out;
  map.read_submap(id, [&](const Submap& s) {
    const SemanticLayer& layer = s.voxels().semantics();
    layer.for_each([&](SemanticLayer::Handle h) {
      const VoxelKey& k = layer.key_of(h);
      out[{k.x(), k.y(), k.z()}] = layer.statistics_of(h);
    });
  });
  return out;
}

TEST(MapStatistics, Format3KeepsThemAndFormat2FilesLoadWithThemUnknown) {
  const fs::path dir = fs::temp_directory_path() / ("slamvdb_map_statistics_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // Weighted observations give each voxel a weight sum other than its count and a spread > 0.
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 8, 11, [](int, VoxelMap& voxels) {
    std::vector<float> x(8);
    for (int i = 0; i < 3; ++i) {
      for (int c = 0; c < 8; ++c) x[c] = 0.1f * (c + i);
      voxels.semantics().integrate({5, 5, 5}, x.data(), 0.5f + static_cast<float>(i));
    }
  });
  const fs::path v3 = dir / "v3.svdb";
  save_map(v3, map);
  const auto before = stored_statistics_by_key(map, 3), after = stored_statistics_by_key(load_map(v3), 3);
  ASSERT_EQ(before.size(), after.size());
  for (const auto& [key, s] : before) {
    EXPECT_EQ(after.at(key).weight, s.weight);
    EXPECT_TRUE(std::isnan(s.spread) ? std::isnan(after.at(key).spread) : after.at(key).spread == s.spread);
  }
  const VoxelStatistics fused = after.at({5, 5, 5});
  EXPECT_FLOAT_EQ(fused.weight, 0.5f + 1.5f + 2.5f);
  EXPECT_TRUE(fused.known());
  EXPECT_GT(fused.spread, 0.f);

  fs::copy_file(v3, dir / "v3.svdb.keep");
  // The same file as format 2 wrote it: no statistics columns.
  set_pragma(v3, "user_version = 2");
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(v3.c_str(), &db), SQLITE_OK);
    for (const char* sql : {"ALTER TABLE semantics DROP COLUMN stats_crc", "ALTER TABLE semantics DROP COLUMN stats"})
      EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sql;
    sqlite3_close(db);
  }
  const SemanticMap old = load_map(v3);
  EXPECT_EQ(old.num_semantic_voxels(), map.num_semantic_voxels());
  old.read_submap(3, [&](const Submap& s) {
    const SemanticLayer& layer = s.voxels().semantics();
    layer.for_each([&](SemanticLayer::Handle h) {
      EXPECT_EQ(layer.weight_of(h), static_cast<float>(layer.count_of(h)));
      EXPECT_FALSE(layer.statistics_of(h).known());
    });
  });
  // Queries read them as unknown: the confidence is the class margin alone, also with the spread
  // factor on, which damps the format-3 map's fused voxel.
  QuerySet queries;
  queries.model_id = "test";
  queries.names = {"a", "b"};
  queries.vectors = QueryMatrix::Zero(2, 8);
  queries.vectors(0, 7) = queries.vectors(1, 0) = 1;
  for (const ClassifiedCell& c : classify_map(old, queries, {}, ModelIdCheck::kIgnore)) {
    EXPECT_FALSE(c.stats.known());
    EXPECT_EQ(c.confidence, class_confidence(c.match, c.count));
    EXPECT_EQ(voxel_confidence(c.match, c.count, c.stats, kMedianSpread), c.confidence);
  }
  std::size_t known = 0, damped = 0;
  for (const ClassifiedCell& c : classify_map(load_map(dir / "v3.svdb.keep"), queries, {}, ModelIdCheck::kIgnore)) {
    EXPECT_EQ(c.confidence, voxel_confidence(c.match, c.count, c.stats));
    known += c.stats.known();
    damped += voxel_confidence(c.match, c.count, c.stats, kMedianSpread) < class_confidence(c.match, c.count);
  }
  EXPECT_GE(known, 1u);
  EXPECT_GE(damped, 1u);  // the voxel of three different observations
  fs::remove_all(dir);
}

// `info` shows the same semantic payload whichever writer made the file: the one that grows a map
// submap by submap (`map`, `slam`) counts the statistics as save_map does.
TEST(MapStatistics, BothWritersCountTheStatisticsInThePayload) {
  const fs::path dir = fs::temp_directory_path() / ("slamvdb_map_payload_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 8, 5);
  const MapFileSummary saved = save_map(dir / "saved.svdb", map);
  auto writer = MapFileWriter::create(dir / "grown.svdb", map.params(), map.info());
  for (const SubmapInfo& s : map.submaps()) writer->save_finished(map, s.id);
  const MapFileSummary grown = writer->finish(map.info(), 0);
  EXPECT_EQ(saved.semantic_payload_bytes, map.num_semantic_voxels() * (12 + 4 + 8 * 2 + 8));
  EXPECT_EQ(grown.semantic_payload_bytes, saved.semantic_payload_bytes);
  EXPECT_EQ(grown.occupancy_payload_bytes, saved.occupancy_payload_bytes);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace slamvdb
