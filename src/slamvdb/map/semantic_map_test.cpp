// The map model: submaps started by path length, pose corrections through the global index,
// cleared voxels leaving it, merges, the running mean at high counts, and concurrent readers.
#include "slamvdb/map/semantic_map.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <random>
#include <set>
#include <thread>

#include "slamvdb/core/error.hpp"

#if defined(__SANITIZE_THREAD__)
#include <tbb/global_control.h>
#endif

namespace slamvdb {
namespace {

#if defined(__SANITIZE_THREAD__)
// Debian's libtbb is not instrumented, so ThreadSanitizer cannot see the synchronisation inside
// TBB's task scheduler and reports its own bookkeeping as races. These tests are about the map's
// locks between the mapping thread and readers (std::thread, instrumented), so TBB runs on the
// calling thread only here; scan integration's own parallelism is tested for determinism elsewhere.
const tbb::global_control kSingleThreadedTbb(tbb::global_control::max_allowed_parallelism, 1);
#endif

// A static world: ground at z = 0 and a wall at y = 6, sampled every 0.2 m.
std::vector<Vec3d> world_points() {
  std::vector<Vec3d> pts;
  for (double x = -10; x <= 70; x += 0.2) {
    for (double y = -6; y <= 6; y += 0.2) pts.emplace_back(x, y, 0.01);
    for (double z = 0.2; z <= 3; z += 0.2) pts.emplace_back(x, 6.01, z);
  }
  return pts;
}

Pose sensor_at(double x, double yaw = 0.0) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(x, 0.0, 1.5);
  return T;
}

// What a sensor at T_world_sensor sees of the world within `range` (no occlusion needed here).
std::vector<Vec3f> scan_of(const std::vector<Vec3d>& world, const Pose& T_world_sensor, double range = 12.0) {
  std::vector<Vec3f> pts;
  const Pose T_sensor_world = T_world_sensor.inverse();
  for (const Vec3d& p : world)
    if ((p - T_world_sensor.translation()).norm() < range) pts.push_back((T_sensor_world * p).cast<float>());
  return pts;
}

MapParams small_params(double submap_length) {
  MapParams p;
  p.semantic = {8, EmbeddingPrecision::kFloat16};
  p.submap_length = submap_length;
  return p;
}

// A stand-in for fusion: every occupied voxel of the active submap observes `value`.
void observe_all(SemanticMap& map, double stamp, const std::vector<float>& value) {
  map.update_active(stamp, [&](VoxelMap& v, const Pose&, std::span<const PlacedVoxelMap>) {
    v.occupancy().for_each_occupied([&](const VoxelKey& k, float) { v.semantics().integrate(k, value.data()); });
  });
}

std::size_t total_entries(const SemanticMap& map) {
  std::size_t refs = 0;
  map.read_index([&](const GlobalIndex& index) { refs = index.num_refs(); });
  return refs;
}

TEST(SemanticMap, SubmapsStartByPathLengthAnchoredAtTheFirstScan) {
  const auto world = world_points();
  SemanticMap map(small_params(10.0));
  for (int i = 0; i <= 35; ++i) map.integrate_scan(i, scan_of(world, sensor_at(i)), sensor_at(i));
  map.finish_active_submap();
  const auto submaps = map.submaps();
  ASSERT_EQ(submaps.size(), 4u);  // 0..9, 10..19, 20..29, 30..35
  for (std::size_t k = 0; k < submaps.size(); ++k) {
    EXPECT_EQ(submaps[k].id, static_cast<int>(k));
    EXPECT_TRUE(submaps[k].finished);
    EXPECT_EQ(submaps[k].T_world_submap.translation(), Vec3d(10.0 * k, 0, 1.5));
    EXPECT_EQ(submaps[k].time_range.begin, 10.0 * k);
    EXPECT_EQ(submaps[k].time_range.end, std::min(10.0 * k + 9, 35.0));
  }
  EXPECT_NEAR(submaps[0].path_length, 10.0, 1e-9);
  EXPECT_NEAR(submaps[3].path_length, 5.0, 1e-9);
  // Every submap holds its surroundings in its own frame: the ground under its anchor is at z = -1.5.
  map.read_submap(2, [](const Submap& s) {
    EXPECT_TRUE(s.voxels().occupancy().is_occupied(s.voxels().occupancy().key_of(Vec3d(0.1, 0.1, -1.49))));
  });
}

TEST(SemanticMap, TheRunningMeanKeepsLearningAfterThousandsOfViews) {
  // The voxel sees class A 5000 times, then class B 5000 times: its mean must be (A + B) / 2.
  const int dim = 8;
  std::vector<float> a(dim, 0.0f), b(dim, 0.0f);
  a[0] = 1.0f, b[1] = 1.0f;
  SemanticMap map(small_params(0.0));
  map.integrate_scan(0, {Vec3f(5.1f, 0.1f, 0.1f)}, Pose::Identity());
  const VoxelKey key(20, 0, 0);
  for (const auto* x : {&a, &b})
    for (int i = 0; i < 5000; ++i)
      map.update_active(1, [&](VoxelMap& v, const Pose&, std::span<const PlacedVoxelMap>) {
        v.semantics().integrate(key, x->data());
      });
  auto mean_at_key = [&] {
    std::vector<float> out(dim), scratch(dim);
    map.read_index([&](const GlobalIndex& index) {
      const auto cell = index.read_at(Vec3d(5.1, 0.1, 0.1), scratch.data());
      ASSERT_TRUE(cell);
      EXPECT_EQ(cell->count, 10000u);
      kernels::decode(cell->embedding, out.data(), out.size());
    });
    return out;
  };
  // While the submap is written (fp32): within 1e-4 of the exact mean.
  std::vector<float> mean = mean_at_key();
  EXPECT_NEAR(mean[0], 0.5f, 1e-4f);
  EXPECT_NEAR(mean[1], 0.5f, 1e-4f);
  // Stored at rest in fp16: within fp16's resolution at 0.5 (2.5e-4) of the exact mean.
  map.finish_active_submap();
  mean = mean_at_key();
  EXPECT_NEAR(mean[0], 0.5f, 5e-4f);
  EXPECT_NEAR(mean[1], 0.5f, 5e-4f);

  // What fp16 accumulation would have done: the mean stops moving long before 10000 views.
  SemanticLayer stuck({dim, EmbeddingPrecision::kFloat16});
  for (const auto* x : {&a, &b})
    for (int i = 0; i < 5000; ++i) stuck.integrate(key, x->data());
  std::vector<float> v(dim);
  stuck.read(*stuck.find(key), v.data());
  EXPECT_GT(std::abs(v[0] - 0.5f), 0.05f) << "fp16 accumulation no longer shows the problem this guards against";
}

TEST(SemanticMap, MovingASubmapMovesExactlyItsVoxelsInIndexReads) {
  const auto world = world_points();
  SemanticMap map(small_params(10.0));
  std::vector<float> value(8, 0.0f);
  for (int i = 0; i < 20; ++i) {
    map.integrate_scan(i, scan_of(world, sensor_at(i)), sensor_at(i));
    value.assign(8, 0.0f);
    value[i < 10 ? 0 : 1] = 1.0f;  // submap 0 sees value e0, submap 1 sees e1
    observe_all(map, i, value);
  }
  map.finish_active_submap();
  ASSERT_EQ(map.num_submaps(), 2u);
  using Cells = std::map<std::tuple<int, int, int>, std::pair<uint32_t, std::vector<float>>>;
  auto cells_of = [&](int dominant) {  // index cells whose mean is dominated by one submap's value
    Cells out;
    map.read_index([&](const GlobalIndex& index) {
      std::vector<float> scratch(8), e(8);
      for (std::size_t i = 0; i < index.size(); ++i) {
        const IndexedVoxel v = index.read(i, scratch.data());
        kernels::decode(v.embedding, e.data(), 8);
        if (v.entries == 1 && e[dominant] > 0.99f) out[{v.cell.x(), v.cell.y(), v.cell.z()}] = {v.count, e};
      }
    });
    return out;
  };
  const Cells before0 = cells_of(0), before1 = cells_of(1);
  ASSERT_GT(before1.size(), 100u);
  const std::size_t entries = total_entries(map);

  Pose moved = map.submap_info(1)->T_world_submap;
  moved.translation() += Vec3d(0, 0, 50.0);  // lifted 50 m: no overlap with submap 0 any more
  map.set_submap_poses({{1, moved}});
  const Cells after0 = cells_of(0), after1 = cells_of(1);
  EXPECT_EQ(total_entries(map), entries);
  // Submap 0's cells did not change; submap 1's cells (its single-entry ones and those it shared)
  // are now exactly 200 cells higher.
  for (const auto& [k, v] : before0) EXPECT_EQ(after0.at(k), v);
  for (const auto& [k, v] : before1) {
    const auto it = after1.find({std::get<0>(k), std::get<1>(k), std::get<2>(k) + 200});
    ASSERT_NE(it, after1.end());
    EXPECT_EQ(it->second, v);
  }
  std::size_t cells_high = 0;
  map.read_index([&](const GlobalIndex& index) {
    for (std::size_t i = 0; i < index.size(); ++i) cells_high += index.key(i).z() > 150;
  });
  map.read_submap(1, [&](const Submap& s) { EXPECT_EQ(cells_high, s.voxels().semantics().size()); });
  EXPECT_THROW(map.set_submap_poses({{7, moved}}), Error);  // no such submap
  Pose scaled = moved;
  scaled.linear() *= 2.0;
  EXPECT_THROW(map.set_submap_poses({{1, scaled}}), Error);  // not rigid
}

// take_finished_submaps: every finished submap leaves in id order with its voxels, the index keeps
// only the active submap's entries (entry by entry then), or empties at once when none is active.
TEST(SemanticMap, TakingEveryFinishedSubmapLeavesOnlyTheActiveOneIndexed) {
  const auto world = world_points();
  SemanticMap map(small_params(10.0));
  const std::vector<float> value{1, 0, 0, 0, 0, 0, 0, 0};
  for (int i = 0; i < 25; ++i) {
    map.integrate_scan(i, scan_of(world, sensor_at(i)), sensor_at(i));
    observe_all(map, i, value);
  }
  ASSERT_EQ(map.num_submaps(), 3u);  // two finished, one active
  std::map<int, std::size_t> sizes;
  for (const SubmapInfo& s : map.submaps())
    map.read_submap(s.id, [&](const Submap& sub) { sizes[s.id] = sub.voxels().semantics().size(); });
  auto taken = map.take_finished_submaps();
  ASSERT_EQ(taken.size(), 2u);
  for (std::size_t i = 0; i < taken.size(); ++i) {
    EXPECT_EQ(taken[i].first.id, static_cast<int>(i));
    EXPECT_EQ(taken[i].second.semantics().size(), sizes.at(static_cast<int>(i)));
  }
  ASSERT_EQ(map.num_submaps(), 1u);
  EXPECT_EQ(total_entries(map), sizes.at(2));  // the active submap's entries only
  map.finish_active_submap();
  taken = map.take_finished_submaps();
  ASSERT_EQ(taken.size(), 1u);
  EXPECT_EQ(map.num_submaps(), 0u);
  EXPECT_EQ(total_entries(map), 0u);
  EXPECT_EQ(map.num_index_cells(), 0u);
  // What left can join another map whole.
  SemanticMap other(small_params(10.0));
  other.add_finished_submap(taken[0].first, std::move(taken[0].second));
  EXPECT_EQ(total_entries(other), sizes.at(2));
}

TEST(SemanticMap, AVoxelClearedByALaterScanLeavesTheIndex) {
  MapParams p = small_params(0.0);
  p.occupancy.min_point_range = 0.0;
  SemanticMap map(p);
  const Vec3d target(5.1, 0.1, 0.1), wall(9.1, 0.1, 0.1);
  map.integrate_scan(0, {target.cast<float>()}, Pose::Identity());
  observe_all(map, 0, std::vector<float>(8, 0.5f));
  std::vector<float> scratch(8);
  auto cell_exists = [&](const Vec3d& p_world) {
    bool found = false;
    map.read_index([&](const GlobalIndex& index) { found = index.read_at(p_world, scratch.data()).has_value(); });
    return found;
  };
  ASSERT_TRUE(cell_exists(target));
  // Rays to a wall behind it pass through the voxel until it is free.
  for (int i = 0; i < 6; ++i) map.integrate_scan(i + 1, {wall.cast<float>()}, Pose::Identity());
  EXPECT_FALSE(cell_exists(target));
  EXPECT_EQ(total_entries(map), map.num_semantic_voxels());
}

// Two passes over the same place, as two submaps: merged, counts add up, no voxel twice, and the
// merged embedding is the count-weighted mean of the two.
TEST(SemanticMap, MergingTwoPassesOverThePlaceAddsCountsAndAverages) {
  const auto world = world_points();
  SemanticMap map(small_params(0.0));
  std::vector<float> a(8, 0.0f), b(8, 0.0f);
  a[0] = 1.0f, b[1] = 1.0f;
  for (int pass = 0; pass < 2; ++pass) {
    // Pass 2 anchors its submap 2 m further (a whole number of voxels), so voxels align exactly.
    map.start_submap(sensor_at(pass * 2.0));
    for (int i = 0; i < 8; ++i) {
      map.integrate_scan(10 * pass + i, scan_of(world, sensor_at(i)), sensor_at(i));
      for (int v = 0; v < (pass ? 1 : 3); ++v) observe_all(map, 10 * pass + i, pass ? b : a);
    }
  }
  map.finish_active_submap();
  ASSERT_EQ(map.num_submaps(), 2u);
  // Expected, per world cell: the count-weighted mean of what the two submaps hold there.
  std::map<std::tuple<int, int, int>, std::pair<uint64_t, std::vector<double>>> expected;
  uint64_t counts_before = 0;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      const SemanticLayer& layer = s.voxels().semantics();
      std::vector<float> e(8);
      layer.for_each([&](SemanticLayer::Handle h) {
        const Vec3d p = s.T_world_submap() * center_of_key(layer.key_of(h), 0.25);
        const IndexCellKey c = key_of_point<IndexCellKey>(p, 4.0);
        auto& [n, sum] = expected[{c.x(), c.y(), c.z()}];
        sum.resize(8, 0.0);
        layer.read(h, e.data());
        for (int k = 0; k < 8; ++k) sum[k] += static_cast<double>(layer.count_of(h)) * e[k];
        n += layer.count_of(h);
        counts_before += layer.count_of(h);
      });
    });
  EXPECT_THROW(map.merge_submaps(0, 0), Error);
  const MergeReport report = map.merge_submaps(0, 1);
  ASSERT_TRUE(report.merged) << report.refused;
  EXPECT_GT(report.overlap, 0.5);
  EXPECT_EQ(report.counts_before, counts_before);
  EXPECT_EQ(report.counts_after + report.counts_dropped_free, counts_before);
  EXPECT_EQ(report.counts_dropped_free, 0u);  // the same static surfaces: nothing turned free
  EXPECT_EQ(map.num_submaps(), 1u);
  EXPECT_FALSE(map.submap_info(1));
  EXPECT_EQ(map.submap_info(0)->time_range.end, 17.0);
  map.read_index([&](const GlobalIndex& index) {
    EXPECT_EQ(index.size(), expected.size());
    EXPECT_EQ(index.num_refs(), index.size());  // one entry per cell: no voxel twice
    std::vector<float> scratch(8), e(8);
    uint64_t counts = 0;
    for (std::size_t i = 0; i < index.size(); ++i) {
      const IndexedVoxel v = index.read(i, scratch.data());
      const auto& [n, sum] = expected.at({v.cell.x(), v.cell.y(), v.cell.z()});
      EXPECT_EQ(v.count, n);
      counts += v.count;
      kernels::decode(v.embedding, e.data(), 8);
      for (int k = 0; k < 8; ++k) EXPECT_NEAR(e[k], sum[k] / static_cast<double>(n), 1e-3);
    }
    EXPECT_EQ(counts, counts_before);
  });
}

TEST(SemanticMap, MergesAreRefusedWithoutOverlapAndForTheActiveSubmap) {
  const auto world = world_points();
  SemanticMap map(small_params(0.0));
  map.start_submap(sensor_at(0));
  map.integrate_scan(0, scan_of(world, sensor_at(0), 5.0), sensor_at(0));
  map.start_submap(sensor_at(40));
  map.integrate_scan(1, scan_of(world, sensor_at(40), 5.0), sensor_at(40));
  EXPECT_THROW(map.merge_submaps(0, 1), Error);  // 1 is still active
  map.finish_active_submap();
  const std::size_t entries = total_entries(map), known = map.num_known_voxels();
  const MergeReport report = map.merge_submaps(0, 1);
  EXPECT_FALSE(report.merged);
  EXPECT_NE(report.refused.find("overlap"), std::string::npos) << report.refused;
  EXPECT_EQ(map.num_submaps(), 2u);
  EXPECT_EQ(total_entries(map), entries);
  EXPECT_EQ(map.num_known_voxels(), known);
}

// Readers of the index and of finished submaps run while the active submap is written, submaps
// are started and finished, and poses are corrected. Run under ThreadSanitizer in CI.
TEST(SemanticMapConcurrency, ReadersWhileTheActiveSubmapIsWritten) {
  const auto world = world_points();
  SemanticMap map(small_params(4.0));
  std::atomic<bool> done{false};
  std::atomic<std::size_t> reads{0};
  auto reader = [&] {
    std::vector<float> scratch(8), e(8);
    while (!done) {
      map.read_index([&](const GlobalIndex& index) {
        for (std::size_t i = 0; i < index.size(); ++i) {
          const IndexedVoxel v = index.read(i, scratch.data());
          kernels::decode(v.embedding, e.data(), 8);
          EXPECT_GT(v.count, 0u);
        }
      });
      for (const SubmapInfo& info : map.submaps())
        if (info.finished)
          map.read_submap(info.id, [&](const Submap& s) { (void)s.voxels().occupancy().num_occupied_voxels(); });
      ++reads;
    }
  };
  auto corrector = [&] {
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> jitter(-0.05, 0.05);
    while (!done) {
      for (const SubmapInfo& info : map.submaps()) {
        if (!info.finished) continue;
        Pose T = info.T_world_submap;
        T.translation().x() += jitter(rng);
        map.set_submap_poses({{info.id, T}});
      }
      (void)map.world_occupancy();
      std::this_thread::yield();
    }
  };
  std::thread r1(reader), r2(reader), c(corrector);
  std::vector<float> value(8, 0.25f);
  for (int i = 0; i < 24; ++i) {
    map.integrate_scan(i, scan_of(world, sensor_at(i), 8.0), sensor_at(i));
    observe_all(map, i, value);
  }
  map.finish_active_submap();
  done = true;
  r1.join(), r2.join(), c.join();
  EXPECT_GT(reads.load(), 0u);
  EXPECT_EQ(map.num_submaps(), 6u);
  EXPECT_EQ(total_entries(map), map.num_semantic_voxels());
}

}  // namespace
}  // namespace slamvdb
