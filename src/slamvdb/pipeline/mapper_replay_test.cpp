// The streaming mapper on a simulated sequence: data that arrives before its poses.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"

namespace slamvdb {
namespace {

using testing::MappingPipelineTest;

// A robot's poses often come late (odometry, then loop closure): every scan and image arrives
// first, from one thread, the poses later from another. Nothing is dropped for arriving early,
// and the map is the one a time-ordered replay gives.
TEST_F(MappingPipelineTest, MapperFusesImagesThatArriveBeforeTheirPoses) {
  const Sequence seq = read_sequence(dir_);
  PipelineOptions o = options();
  o.max_scans = 30;
  EncoderFeatureSource in_order_source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                                       EncoderFeatureSource::Input::kLabels);
  PipelineReport in_order;
  const SemanticMap reference = build_map(seq, &in_order_source, o, in_order);
  ASSERT_GT(in_order.images_fused, 5u);

  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  MapperOptions m = mapper_options(seq, o);
  m.max_queued_items = 1000;
  Mapper mapper(m, SemanticMap(o.map), &source);
  const double last_scan = seq.scans[29].stamp;
  for (std::size_t i = 0; i < 30; ++i) ASSERT_TRUE(mapper.add_scan(seq.scans[i].stamp, read_scan(seq.scans[i]).points));
  for (const ImageRecord& image : seq.images)
    if (image.stamp <= last_scan) {
      ASSERT_TRUE(mapper.add_image(image));
    }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(mapper.report().scans_integrated, 0u);  // nothing can be placed yet
  std::thread poses([&] {
    for (std::size_t i = 0; i < seq.poses.size(); ++i) mapper.add_pose(seq.poses.stamps()[i], seq.poses.poses()[i]);
  });
  poses.join();
  const SemanticMap map = mapper.finish();
  const PipelineReport r = mapper.report();
  EXPECT_EQ(r.scans_integrated, 30u);
  EXPECT_EQ(r.images_fused, in_order.images_fused);
  EXPECT_EQ(r.images_outside_pose_range, in_order.images_outside_pose_range);
  EXPECT_EQ(r.sensor_items_dropped(), in_order.sensor_items_dropped());
  testing::expect_same_index_cells(map, reference);
}

}  // namespace
}  // namespace slamvdb
