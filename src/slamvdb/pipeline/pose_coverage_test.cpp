// Poses that cover only part of the data: a trajectory that starts late, ends early or has a gap
// longer than the mapper's queue. `map --poses` used to hang (the replay waited for room in a
// queue full of items that waited for a pose the replay itself would give next); every run must
// finish, with the items no pose covers counted as outside the pose range, not as "queue full".
// The same for `slam`, whose images wait for the next scan's pose, over a run of unreadable scans.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <future>
#include <optional>
#include <regex>

#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/pipeline/slam_mapping.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::MappingPipelineTest;
using testing::quote_path;

// The numbers of a report line "scans: 5 integrated of 9 (0 unreadable, 4 outside the pose range,
// ...)" or "images: ...": used, total, outside the pose range, dropped on a full queue.
struct StreamCounts {
  std::size_t used = 0, total = 0, outside = 0, queue_full = 0;
};
std::optional<StreamCounts> report_counts(const std::string& output, bool scans) {
  static const std::regex scan_line(
      R"(scans: (\d+) integrated of (\d+) \(\d+ unreadable, (\d+) outside the pose range, \d+ out of order, \d+ )"
      R"(duplicate stamps, (\d+) dropped on a full queue)");
  static const std::regex image_line(
      R"(images: (\d+) fused of (\d+) \(\d+ failed, (\d+) outside the pose range, \d+ before the first scan, \d+ out )"
      R"(of order, \d+ duplicate stamps, (\d+) dropped on a full queue)");
  std::smatch m;
  if (!std::regex_search(output, m, scans ? scan_line : image_line)) return std::nullopt;
  return StreamCounts{std::stoul(m[1].str()), std::stoul(m[2].str()), std::stoul(m[3].str()), std::stoul(m[4].str())};
}

struct PartialPoses {
  std::string name;
  std::vector<double> stamps;
  std::vector<Pose> poses;
};

TEST_F(MappingPipelineTest, MapWithPosesCoveringPartOfTheDataFinishesAndCountsTheRest) {
  const Sequence seq = read_sequence(dir_);
  constexpr std::size_t kScans = 40;  // --max-scans: 4 s of data (and of --realtime)
  ASSERT_GE(seq.poses.size(), 60u);
  const auto rows = [&](PartialPoses& p, std::size_t from, std::size_t to, double shift = 0.0) {
    for (std::size_t i = from; i < to; ++i) {
      p.stamps.push_back(seq.poses.stamps()[i] + shift);
      p.poses.push_back(seq.poses.poses()[i]);
    }
  };
  const std::size_t n = seq.poses.size();
  std::vector<PartialPoses> cases(4);
  cases[0].name = "late_start", rows(cases[0], 20, n);  // the first 20 rows removed
  cases[1].name = "shifted", rows(cases[1], 0, n, 2.0);  // every stamp 2 s later
  cases[2].name = "late_end", rows(cases[2], 0, 20);     // ends halfway through the 40 scans
  cases[3].name = "gappy", rows(cases[3], 0, 5), rows(cases[3], 30, n);  // 2.5 s without a pose
  const double last_scan = seq.scans[kScans - 1].stamp;
  for (const bool realtime : {false, true})
    for (const PartialPoses& c : cases) {
      SCOPED_TRACE(c.name + (realtime ? " --realtime" : ""));
      const fs::path file = dir_ / (c.name + ".tum"), out = dir_ / (c.name + ".svdb");
      write_trajectory(file, c.stamps, c.poses, PoseFormat::kTum);
      const Trajectory covered(c.stamps, c.poses);
      std::size_t scans_covered = 0, images = 0, images_outside = 0;
      // Items that wait for the same pose (the first at or after their stamp; none after the last).
      std::map<std::size_t, std::size_t> waiting_for;
      const auto wait_for_pose = [&](double stamp) {
        ++waiting_for[std::lower_bound(c.stamps.begin(), c.stamps.end(), stamp) - c.stamps.begin()];
      };
      for (std::size_t i = 0; i < kScans; ++i) {
        scans_covered += covered.at(seq.scans[i].stamp).has_value();
        wait_for_pose(seq.scans[i].stamp);
      }
      for (const ImageRecord& image : seq.images)
        if (image.stamp <= last_scan) ++images, images_outside += !covered.at(image.stamp), wait_for_pose(image.stamp);
      std::size_t most_waiting = 0;
      for (const auto& [pose, items] : waiting_for) most_waiting = std::max(most_waiting, items);
      ASSERT_GT(most_waiting, 16u);  // more than the queue holds wait for one pose (or for none)
      const auto t0 = std::chrono::steady_clock::now();
      const auto r = testing::run_cli(fmt::format("map {} -o {} --poses {} --pose-format tum --max-scans {} --dim 16 "
                                                  "--feature-size 64x40{}",
                                                  quote_path(dir_), quote_path(out), quote_path(file), kScans,
                                                  realtime ? " --realtime" : ""),
                                      60.0);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      ASSERT_FALSE(r.timed_out) << "hung: " << r.output;
      ASSERT_EQ(r.exit_code, 0) << r.output;
      std::cout << c.name << (realtime ? " --realtime" : "") << ": " << seconds << " s\n";
      const auto scans = report_counts(r.output, true), frames = report_counts(r.output, false);
      ASSERT_TRUE(scans && frames) << r.output;
      EXPECT_EQ(scans->total, kScans);
      EXPECT_EQ(scans->outside, kScans - scans_covered) << r.output;
      EXPECT_EQ(frames->total, images);
      EXPECT_EQ(frames->outside, images_outside) << r.output;
      if (!realtime) {  // a replay waits for room: nothing is dropped
        EXPECT_EQ(scans->used, scans_covered) << r.output;
        EXPECT_EQ(scans->queue_full + frames->queue_full, 0u) << r.output;
      } else {  // frames are dropped only when the mapper falls behind, never for want of a pose
        EXPECT_EQ(scans->used + scans->queue_full, scans_covered) << r.output;
      }
    }
}

// `slam` gives each image once the pose after it is given (the next readable scan's): a run of
// unreadable scans longer than the mapper's queue used to leave the images waiting in a full
// queue for a pose the same thread would give only after them.
TEST(SlamPoses, ImagesAcrossARunOfUnreadableScansAreFusedNotDropped) {
  testing::TempDir tmp;
  const fs::path dir = tmp.path / "seq";
  synth::SynthConfig config;
  config.length_m = 12.0;
  config.image_width = 160;
  config.image_height = 100;
  config.lidar.columns = 256;
  synth::write_synthetic_sequence(config, dir, true);
  Sequence seq = read_sequence(dir);
  ASSERT_GE(seq.scans.size(), 20u);
  for (std::size_t i = 5; i < 13; ++i) fs::resize_file(seq.scans[i].points, 5);  // not whole points: unreadable

  SlamMappingOptions options;
  options.pipeline.map.semantic.dim = 16;
  options.pipeline.queue_capacity = 2;
  options.tracking.loop_closure = false;
  SimulatedEncoderConfig encoder = SimulatedEncoderConfig::clean();  // mapping mechanics
  encoder.dim = 16;
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder), EncoderFeatureSource::Input::kLabels);
  auto run = std::async(std::launch::async, [&] { return map_with_own_poses(seq, &source, options); });
  ASSERT_EQ(run.wait_for(std::chrono::seconds(45)), std::future_status::ready) << "slam hung";
  const PipelineReport r = run.get().report;
  EXPECT_EQ(r.scans_failed, 8u);
  EXPECT_EQ(r.scans_queue_full + r.inference.dropped_queue_full, 0u) << r.summary();
  std::size_t images = 0;  // those up to the last scan are part of the run
  for (const ImageRecord& image : seq.images) images += image.stamp <= seq.scans.back().stamp;
  EXPECT_EQ(r.images_total, images);
  EXPECT_EQ(r.images_outside_pose_range, 0u) << r.summary();
  EXPECT_GT(r.images_fused, 0u);
}

}  // namespace
}  // namespace slamvdb
