// The memory estimate that refuses mapping runs which cannot finish, against what the occupancy
// grid really creates from a SIMULATED scan.
#include "memory_checks.hpp"

#include <gtest/gtest.h>

#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::cli {
namespace {

TEST(MemoryChecks, EstimateFollowsTheBlocksOneScanCreates) {
  testing::TempDir tmp;
  synth::SynthConfig config;
  config.length_m = 1.0;
  config.image_width = 32;
  config.image_height = 20;
  synth::write_synthetic_sequence(config, tmp.path / "seq");
  const Sequence seq = read_sequence(tmp.path / "seq");
  const LidarScan scan = read_scan(seq.scans.front());
  for (const double voxel_size : {0.25, 0.1}) {
    OccupancyParams params;
    params.voxel_size = voxel_size;
    OccupancyGrid grid(params);
    grid.integrate_scan(scan.points, *seq.poses.at(seq.scans.front().stamp));
    const double estimate = estimate_scan_memory(params, 512).occupancy_blocks;
    EXPECT_GT(estimate, 0.6 * static_cast<double>(grid.num_blocks())) << voxel_size;
    EXPECT_LT(estimate, 1.6 * static_cast<double>(grid.num_blocks())) << voxel_size;
    EXPECT_GE(estimate_scan_memory(params, 512).occupancy_bytes, 0.8 * static_cast<double>(grid.memory_bytes()));
  }
}

}  // namespace
}  // namespace slamvdb::cli
