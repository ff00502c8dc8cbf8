// The streaming mapper: asynchronous input in any arrival order, counted drops, bounded queues.
#include "slamvdb/pipeline/mapper.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <atomic>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/mapper_fixtures.hpp"

namespace slamvdb {
namespace {

using testing::at_x;
using testing::small_camera;
using testing::unit_features;
using testing::wall_ahead;

// Out-of-order and duplicate stamps, poses that are no rigid transform and items no pose ever
// covers are counted by reason; none of them stops the mapper.
TEST(Mapper, CountsOutOfOrderDuplicateAndUncoveredInputByReason) {
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.camera = small_camera();
  Mapper mapper(m, SemanticMap(m.map));
  EXPECT_TRUE(mapper.add_pose(0.0, at_x(0)));
  EXPECT_TRUE(mapper.add_pose(1.0, at_x(0.1)));
  EXPECT_FALSE(mapper.add_pose(1.0, at_x(0.1)));  // duplicate
  EXPECT_FALSE(mapper.add_pose(0.5, at_x(0.1)));  // out of order
  Pose scaled = at_x(0);
  scaled.linear() *= 2.0;
  EXPECT_FALSE(mapper.add_pose(3.0, scaled));  // not rigid
  EXPECT_FALSE(mapper.add_pose(std::nan(""), at_x(0)));
  EXPECT_TRUE(mapper.add_pose(2.0, at_x(0.2)));

  EXPECT_FALSE(mapper.add_features(-1.0, unit_features(8)));  // before the first pose: never covered, counted
  EXPECT_TRUE(mapper.add_scan(0.5, wall_ahead()));
  EXPECT_FALSE(mapper.add_scan(0.5, wall_ahead()));  // duplicate
  EXPECT_FALSE(mapper.add_scan(0.25, wall_ahead()));  // out of order
  EXPECT_TRUE(mapper.add_features(0.75, unit_features(8)));
  EXPECT_FALSE(mapper.add_features(0.75, unit_features(8)));
  EXPECT_FALSE(mapper.add_features(0.6, unit_features(8)));
  FeatureMap poisoned = unit_features(8, std::nanf(""));
  EXPECT_TRUE(mapper.add_features(0.9, std::move(poisoned)));  // refused whole by fusion, counted
  EXPECT_TRUE(mapper.add_scan(1.5, wall_ahead()));
  EXPECT_TRUE(mapper.add_scan(7.0, wall_ahead()));  // after the last pose: never covered
  const SemanticMap map = mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.poses_total, 7u);
  EXPECT_EQ(r.poses_duplicate, 1u);
  EXPECT_EQ(r.poses_out_of_order, 1u);
  EXPECT_EQ(r.poses_invalid, 2u);
  EXPECT_EQ(r.scans_total, 5u);
  EXPECT_EQ(r.scans_integrated, 2u);
  EXPECT_EQ(r.scans_duplicate, 1u);
  EXPECT_EQ(r.scans_out_of_order, 1u);
  EXPECT_EQ(r.scans_without_pose, 1u);
  EXPECT_EQ(r.images_total, 5u);
  EXPECT_EQ(r.images_outside_pose_range, 1u);
  EXPECT_EQ(r.images_duplicate, 1u);
  EXPECT_EQ(r.images_out_of_order, 1u);
  EXPECT_EQ(r.images_fused, 1u);
  EXPECT_EQ(r.images_failed, 1u);
  EXPECT_GT(map.num_semantic_voxels(), 0u);
  EXPECT_EQ(r.problems.size(), 11u);  // one line per item not used
}

// A feature source slower than the frames with the live policy: frames that find the queue full
// are dropped and counted (the caller never waits); every frame is accounted for.
TEST(Mapper, LivePolicyDropsAndCountsFramesThatFindTheQueueFull) {
  struct SlowSource : FeatureSource {
    FeatureMap features_for(const ImageRecord&) override {
      std::this_thread::sleep_for(std::chrono::milliseconds(30));
      return unit_features(8);
    }
    std::string model_id() const override { return "slow"; }
  } slow;
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.camera = small_camera();
  m.policy = QueuePolicy::kDropWhenFull;
  m.max_queued_items = 2;
  Mapper mapper(m, SemanticMap(m.map), &slow);
  mapper.add_pose(0.0, at_x(0));
  mapper.add_pose(100.0, at_x(1));
  std::size_t taken = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 1; i <= 12; ++i) {
    ImageRecord image;
    image.stamp = i;
    taken += mapper.add_image(image);
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(200));  // never waited for the network
  mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_GT(r.inference.dropped_queue_full, 0u);
  EXPECT_EQ(r.inference.dropped_queue_full + taken, 12u);
  EXPECT_EQ(r.images_before_first_scan, taken);  // no scan: nothing to fuse into, counted as such
}

// The byte bound holds (replay waits for room instead of growing); a caller that waits for room
// while the mapper waits for a pose only that caller could bring gets a counted drop after
// max_wait_seconds, not a deadlock; after end_poses() nothing waits for a pose.
TEST(Mapper, QueueBytesStayBoundedAndAWaitThatCouldNeverEndIsADrop) {
  MapperOptions m;
  m.map.semantic.dim = 8;
  const std::size_t scan_bytes = wall_ahead().size() * sizeof(Vec3f);
  m.max_queued_bytes = 3 * scan_bytes;
  {
    Mapper mapper(m, SemanticMap(m.map));
    mapper.add_pose(0.0, at_x(0));
    mapper.add_pose(100.0, at_x(10));
    for (int i = 1; i <= 40; ++i) ASSERT_TRUE(mapper.add_scan(i, wall_ahead()));
    mapper.finish();
    const PipelineReport r = mapper.report();
    EXPECT_EQ(r.scans_integrated, 40u);
    EXPECT_LE(r.peak_queued_bytes, 3 * scan_bytes);
  }
  m.max_wait_seconds = 0.05;
  {
    Mapper mapper(m, SemanticMap(m.map));
    mapper.add_pose(0.0, at_x(0));
    std::size_t taken = 0;
    for (int i = 1; i <= 6; ++i) taken += mapper.add_scan(i, wall_ahead());  // no pose covers any yet
    EXPECT_EQ(taken, 3u);
    mapper.add_pose(100.0, at_x(10));
    mapper.finish();
    const PipelineReport r = mapper.report();
    EXPECT_EQ(r.scans_queue_full, 3u);
    EXPECT_EQ(r.scans_integrated, 3u);
  }
  m.max_wait_seconds = 1e6;
  Mapper mapper(m, SemanticMap(m.map));
  mapper.add_pose(0.0, at_x(0));
  mapper.add_pose(3.0, at_x(1));
  mapper.end_poses();
  for (int i = 1; i <= 10; ++i) EXPECT_EQ(mapper.add_scan(i, wall_ahead()), i <= 3);  // 4..10: never covered
  mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_integrated, 3u);
  EXPECT_EQ(r.scans_without_pose, 7u);
}

TEST(Mapper, FeaturesOfTheWrongDimensionAreAnErrorAtFinish) {
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.camera = small_camera();
  Mapper mapper(m, SemanticMap(m.map));
  mapper.add_pose(0.0, at_x(0));
  mapper.add_pose(2.0, at_x(0));
  mapper.add_scan(0.5, wall_ahead());
  mapper.add_features(1.0, unit_features(16));
  try {
    mapper.finish();
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("16 channels"), std::string::npos) << e.what();
  }
}

// Everything at once, as on a robot: scans, feature maps and poses from three threads, while a
// loop closer moves and merges finished submaps and a reader reads the index. Built under
// ThreadSanitizer in CI (scripts/test_tsan.sh); here it checks that every item is accounted for.
TEST(Mapper, StreamsFromSeveralThreadsWhileSubmapsAreMovedMergedAndRead) {
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.map.submap_length = 1.0;
  m.camera = small_camera();
  m.max_queued_items = 8;
  Mapper mapper(m, SemanticMap(m.map));
  constexpr int kFrames = 80;
  auto stamp = [](int i) { return 0.1 * i; };
  std::thread poses([&] {
    for (int i = 0; i <= kFrames; ++i) {
      mapper.add_pose(stamp(i), at_x(0.1 * i));
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
  });
  std::thread scans([&] {
    for (int i = 0; i < kFrames; ++i) mapper.add_scan(stamp(i) + 0.01, wall_ahead());
  });
  std::thread images([&] {
    for (int i = 0; i < kFrames; ++i) mapper.add_features(stamp(i) + 0.05, unit_features(8));
  });
  std::atomic<bool> stop{false};
  std::size_t moves = 0, merges = 0, reads = 0;
  std::thread closer([&] {
    while (!stop) {
      const std::vector<SubmapInfo> submaps = mapper.map().submaps();
      std::optional<int> previous;
      for (const SubmapInfo& s : submaps) {
        if (!s.finished) continue;
        try {
          Pose T = s.T_world_submap;
          T.translation().z() += 1e-3;
          mapper.correct_submaps({{s.id, T}});
          ++moves;
          if (previous && mapper.merge_submaps(*previous, s.id, {.min_overlap = 0.0}).refused.empty()) ++merges;
        } catch (const Error&) {  // merged away meanwhile
        }
        previous = s.id;
      }
      mapper.map().read_index([&](const GlobalIndex& index) { reads += index.size() > 0; });
    }
  });
  poses.join(), scans.join(), images.join();
  while (mapper.report().scans_integrated + mapper.report().scans_queue_full < kFrames)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  stop = true;
  closer.join();
  const SemanticMap map = mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_integrated, static_cast<std::size_t>(kFrames));
  EXPECT_EQ(r.images_fused + r.images_before_first_scan + r.images_failed, static_cast<std::size_t>(kFrames));
  EXPECT_EQ(r.sensor_items_dropped(), r.images_before_first_scan);
  EXPECT_GT(moves, 0u);
  EXPECT_GT(map.num_semantic_voxels(), 0u);
}

// wait_until_idle returns once everything the poses cover is in the map, and does not wait for
// what only a later pose can cover (a loop closer calls it between two scans).
TEST(Mapper, WaitUntilIdleHoldsEveryCoveredItemAndLeavesTheRestQueued) {
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.camera = small_camera();
  Mapper mapper(m, SemanticMap(m.map));
  mapper.wait_until_idle();  // nothing given yet
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(mapper.add_pose(i, at_x(0.1 * i)));
    ASSERT_TRUE(mapper.add_scan(i, wall_ahead()));
  }
  ASSERT_TRUE(mapper.add_features(4.5, unit_features(8)));  // waits for a pose after 4.5 s
  mapper.wait_until_idle();
  PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_integrated, 5u);
  EXPECT_EQ(r.images_fused, 0u);
  EXPECT_GT(mapper.map().num_occupied_voxels(), 0u);
  ASSERT_TRUE(mapper.add_pose(5, at_x(0.5)));
  mapper.wait_until_idle();
  EXPECT_EQ(mapper.report().images_fused, 1u);
  mapper.finish();
}

}  // namespace
}  // namespace slamvdb
