// The streaming mapper's waits all end: items no pose can cover never wait for room, a stall for a
// pose is bounded once (not once per item), and the inference thread is woken whenever the
// mapping thread takes an item. Also built under ThreadSanitizer (slamvdb_concurrency_tests).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>

#include "slamvdb/pipeline/mapper.hpp"
#include "slamvdb/testing/mapper_fixtures.hpp"

namespace slamvdb {
namespace {

using testing::at_x;
using testing::small_camera;
using testing::unit_features;
using testing::wall_ahead;
using WaitClock = std::chrono::steady_clock;

double seconds_from(WaitClock::time_point t0) {
  return std::chrono::duration<double>(WaitClock::now() - t0).count();
}

MapperOptions waits_options() {
  MapperOptions m;
  m.map.semantic.dim = 8;
  m.camera = small_camera();
  return m;
}

// The queue is full of scans waiting for a later pose; an image from before the first pose can
// never be covered (poses only extend the trajectory at its end), so it is counted as outside the
// pose range at once instead of waiting for room (it used to wait max_wait_seconds, then be
// counted as "queue full"). After end_poses() the same holds for items after the last pose.
TEST(MapperWaits, ItemsNoPoseCanCoverNeverWaitForRoom) {
  MapperOptions m = waits_options();
  m.max_queued_items = 2;
  m.max_wait_seconds = 3.0;
  Mapper mapper(m, SemanticMap(m.map));
  ASSERT_TRUE(mapper.add_pose(10.0, at_x(0)));
  ASSERT_TRUE(mapper.add_scan(11.0, wall_ahead()));  // both wait for a pose after 10 s
  ASSERT_TRUE(mapper.add_scan(12.0, wall_ahead()));
  auto t0 = WaitClock::now();
  EXPECT_FALSE(mapper.add_features(5.0, unit_features(8)));  // before the first pose
  EXPECT_LT(seconds_from(t0), 1.0);
  PipelineReport r = mapper.report();
  EXPECT_EQ(r.images_outside_pose_range, 1u);
  EXPECT_EQ(r.inference.dropped_queue_full, 0u);

  ASSERT_TRUE(mapper.add_pose(13.0, at_x(0.1)));
  mapper.end_poses();
  t0 = WaitClock::now();
  EXPECT_FALSE(mapper.add_scan(14.0, wall_ahead()));  // after the last pose, the poses have ended
  EXPECT_FALSE(mapper.add_features(15.0, unit_features(8)));
  EXPECT_LT(seconds_from(t0), 1.0);
  mapper.finish();
  r = mapper.report();
  EXPECT_EQ(r.scans_integrated, 2u);
  EXPECT_EQ(r.scans_without_pose, 1u);
  EXPECT_EQ(r.images_outside_pose_range, 2u);
  EXPECT_EQ(r.scans_queue_full + r.inference.dropped_queue_full, 0u);
}

// A caller that gives the poses itself and waits for room while the mapper waits for a pose: one
// wait of max_wait_seconds, then every item that finds the queue full is dropped at once until a
// pose comes (it used to be max_wait_seconds for each item: an hour for a minute of data).
TEST(MapperWaits, AStallForAPoseIsBoundedOnceNotOncePerItem) {
  MapperOptions m = waits_options();
  m.max_queued_items = 2;
  m.max_wait_seconds = 0.5;
  Mapper mapper(m, SemanticMap(m.map));
  ASSERT_TRUE(mapper.add_pose(0.0, at_x(0)));
  const auto t0 = WaitClock::now();
  std::size_t taken = 0;
  for (int i = 1; i <= 6; ++i) taken += mapper.add_scan(i, wall_ahead());  // no pose covers any yet
  const double waited = seconds_from(t0);
  EXPECT_EQ(taken, 2u);
  EXPECT_GE(waited, 0.45);
  EXPECT_LT(waited, 1.25) << "each of the 4 items waited max_wait_seconds";
  ASSERT_TRUE(mapper.add_pose(100.0, at_x(10)));  // the clock starts again: room comes
  EXPECT_TRUE(mapper.add_scan(7.0, wall_ahead()));
  mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_queue_full, 4u);
  EXPECT_EQ(r.scans_integrated, 3u);
  ASSERT_FALSE(r.problems.empty());
  EXPECT_NE(r.problems.front().find("waited"), std::string::npos) << r.problems.front();
}

// The inference thread leaves an image alone while the queue is over its byte bound, unless the
// image is the mapper's next item. Both change when the mapping thread takes an item, which must
// wake the inference thread: here, when image a is done, the bound (a feature map is larger than
// it) keeps image b waiting behind a; the mapping thread then takes a, and nothing else happens.
// It used to wait for b's features while the inference thread waited for a wake-up that never came.
TEST(MapperWaits, TheEncoderIsWokenWhenTheMapperTakesAnItem) {
  struct GatedSource : FeatureSource {
    std::atomic<bool> open{false};
    FeatureMap features_for(const ImageRecord& record) override {
      while (record.stamp == 2.0 && !open) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      return unit_features(8, 1.0f, 80, 100);  // 256 kB
    }
    std::string model_id() const override { return "gated"; }
  } source;
  MapperOptions m = waits_options();
  const std::size_t scan_bytes = wall_ahead().size() * sizeof(Vec3f);
  m.max_queued_bytes = 2 * scan_bytes;  // a scan fits, a feature map does not
  ASSERT_GT(unit_features(8, 1.0f, 80, 100).bytes(), m.max_queued_bytes);
  Mapper mapper(m, SemanticMap(m.map), &source);
  ASSERT_TRUE(mapper.add_scan(1.0, wall_ahead()));
  ImageRecord a, b;
  a.stamp = 2.0, b.stamp = 3.0;
  ASSERT_TRUE(mapper.add_image(a));  // the encoder holds it until the gate opens
  ASSERT_TRUE(mapper.add_image(b));  // queued at 0 bytes while a is being encoded
  ASSERT_TRUE(mapper.add_pose(0.0, at_x(0)));
  ASSERT_TRUE(mapper.add_pose(10.0, at_x(0)));
  for (int i = 0; i < 5000 && mapper.report().scans_integrated < 1; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_EQ(mapper.report().scans_integrated, 1u);  // the mapping thread now waits for a's features
  source.open = true;  // a done: over the bound with a queued, b is not next, so b waits
  auto idle = std::async(std::launch::async, [&] { mapper.wait_until_idle(); });
  EXPECT_EQ(idle.wait_for(std::chrono::seconds(10)), std::future_status::ready)
      << "the mapper waits for image b's features, the encoder for a wake-up";
  mapper.finish();  // also ends a wait_until_idle that hung
  idle.wait();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_integrated, 1u);
  EXPECT_EQ(r.inference.completed, 2u);
  EXPECT_EQ(r.images_fused, 2u);
}

}  // namespace
}  // namespace slamvdb
