#pragma once
// Test helpers for the map store: a fixture with its own directory, maps with awkward values,
// bit-level comparison of two maps, and file byte helpers.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::testing {
namespace fs = std::filesystem;

class MapStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("slamvdb_map_store_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

inline Pose make_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Two submaps with negative keys, boundary and odd float values (-0, subnormal, NaN with a payload,
// an all-unknown block) and embeddings with subnormal, signed-zero and extreme fp16 values.
inline SemanticMap make_map(EmbeddingPrecision precision, int dim, int seed,
                     const std::function<void(int id, VoxelMap&)>& edit = {}) {
  MapParams params;
  params.occupancy.voxel_size = 0.2;
  params.occupancy.clamp_max = 3.25f;
  params.semantic = {dim, precision};
  SemanticMap map(params, {.model_id = "simulated-clip-test",
                           .ontology = "rellis3d",
                           .source = "SIMULATED unit-test map, seed " + std::to_string(seed)});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> lo(-2.0f, 3.25f), unit(-1.0f, 1.0f);
  std::uniform_int_distribution<int> coord(-40, 40);
  std::uniform_int_distribution<uint32_t> count(1, 100000);
  std::vector<float> e(dim);
  for (const auto& [id, pose, t0] : {std::tuple{3, make_pose(0.3, {1.5, -2.25, 0.125}), 10.0},
                                      std::tuple{-7, make_pose(-2.0, {100.0, 40.0, -3.0}), 20.0}}) {
    VoxelMap voxels(params);
    OccupancyGrid& grid = voxels.occupancy();
    for (int i = 0; i < 3000; ++i) grid.set_log_odds({coord(rng), coord(rng), coord(rng)}, lo(rng));
    grid.set_log_odds({-1, -1, -1}, -0.0f);
    grid.set_log_odds({-2, -1, -1}, std::numeric_limits<float>::denorm_min());
    grid.set_log_odds({-3, -1, -1}, std::bit_cast<float>(0x7fc00123u));  // unknown, unusual NaN bits
    grid.set_log_odds({800, 800, 800}, std::numeric_limits<float>::quiet_NaN());  // a block with no known voxel
    SemanticLayer& layer = voxels.semantics();
    int n = 0;
    grid.for_each_occupied([&](const VoxelKey& k, float) {
      if (n++ % 2) return;
      for (float& x : e) x = unit(rng);
      layer.set(k, e.data(), count(rng));
    });
    e.assign(dim, 0.0f);
    e[0] = -0.0f, e[1] = 65504.0f, e[2] = 6e-8f, e[3] = -1e-5f;
    layer.set({-1, -1, -1}, e.data(), UINT32_MAX);
    SubmapInfo info;
    info.id = id;
    info.T_world_submap = pose;
    info.time_range = {t0, t0 + 4.5};
    info.path_length = 12.5;
    if (edit) edit(id, voxels);
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

inline void expect_same_params(const MapParams& a, const MapParams& b) {
  EXPECT_EQ(a.occupancy.voxel_size, b.occupancy.voxel_size);
  EXPECT_EQ(a.occupancy.log_odds_hit, b.occupancy.log_odds_hit);
  EXPECT_EQ(a.occupancy.log_odds_miss, b.occupancy.log_odds_miss);
  EXPECT_EQ(a.occupancy.clamp_min, b.occupancy.clamp_min);
  EXPECT_EQ(a.occupancy.clamp_max, b.occupancy.clamp_max);
  EXPECT_EQ(a.occupancy.occupied_threshold, b.occupancy.occupied_threshold);
  EXPECT_EQ(a.occupancy.min_point_range, b.occupancy.min_point_range);
  EXPECT_EQ(a.occupancy.max_point_range, b.occupancy.max_point_range);
  EXPECT_EQ(a.occupancy.max_clearing_range, b.occupancy.max_clearing_range);
  EXPECT_EQ(a.semantic.dim, b.semantic.dim);
  EXPECT_EQ(a.semantic.precision, b.semantic.precision);
}

// Bit-level comparison: every log-odds (NaN payloads included) and every embedding value.
inline void expect_identical(const SemanticMap& a, const SemanticMap& b) {
  expect_same_params(a.params(), b.params());
  EXPECT_EQ(a.params().submap_length, b.params().submap_length);
  EXPECT_EQ(a.info().model_id, b.info().model_id);
  EXPECT_EQ(a.info().ontology, b.info().ontology);
  EXPECT_EQ(a.info().source, b.info().source);
  const auto infos_a = a.submaps(), infos_b = b.submaps();
  ASSERT_EQ(infos_a.size(), infos_b.size());
  for (std::size_t i = 0; i < infos_a.size(); ++i) {
    const SubmapInfo &ia = infos_a[i], &ib = infos_b[i];
    EXPECT_EQ(ia.id, ib.id);
    EXPECT_EQ(ia.T_world_submap.matrix(), ib.T_world_submap.matrix());
    EXPECT_EQ(ia.time_range.begin, ib.time_range.begin);
    EXPECT_EQ(ia.time_range.end, ib.time_range.end);
    EXPECT_EQ(ia.path_length, ib.path_length);
    a.read_submap(ia.id, [&](const Submap& sa) {
      b.read_submap(ib.id, [&](const Submap& sb) {
        expect_same_params(sa.voxels().params(), sb.voxels().params());
        const OccupancyGrid &ga = sa.voxels().occupancy(), &gb = sb.voxels().occupancy();
        ASSERT_EQ(ga.num_blocks(), gb.num_blocks());
        EXPECT_EQ(ga.num_occupied_voxels(), gb.num_occupied_voxels());
        for (const auto& [bk, block] : ga.blocks()) {
          const auto it = gb.blocks().find(bk);
          ASSERT_NE(it, gb.blocks().end()) << bk.transpose();
          for (int v = 0; v < kBlockVoxels; ++v) {
            ASSERT_EQ(std::bit_cast<uint32_t>(block->cells[v].log_odds),
                      std::bit_cast<uint32_t>(it->second->cells[v].log_odds))
                << "block " << bk.transpose() << " voxel " << v;
            ASSERT_EQ(block->occupied(v), it->second->occupied(v));
          }
        }
        const SemanticLayer &la = sa.voxels().semantics(), &lb = sb.voxels().semantics();
        ASSERT_EQ(la.size(), lb.size());
        std::vector<float> ea(la.dim()), eb(la.dim());
        la.for_each([&](SemanticLayer::Handle h) {
          const VoxelKey& k = la.key_of(h);
          const auto other = lb.find(k);
          ASSERT_TRUE(other) << k.transpose();
          EXPECT_EQ(la.count_of(h), lb.count_of(*other));
          la.read(h, ea.data());
          lb.read(*other, eb.data());
          ASSERT_EQ(std::memcmp(ea.data(), eb.data(), ea.size() * sizeof(float)), 0) << k.transpose();
        });
      });
    });
  }
}

inline std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path().filename());
  std::sort(files.begin(), files.end());
  return files;
}

inline std::string load_error(const fs::path& path) {
  try {
    load_map(path);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "loading " << path << " did not throw";
  return {};
}

inline std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

inline void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

inline void set_pragma(const fs::path& file, const std::string& pragma) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, ("PRAGMA " + pragma).c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

}  // namespace slamvdb::testing
