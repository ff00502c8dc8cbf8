#include "option_checks.hpp"

#include <gtest/gtest.h>

#include "map_option_checks.hpp"
#include "memory_checks.hpp"

namespace slamvdb::cli {
namespace {

std::string check(const CLI::Validator& v, std::string text) { return v(text); }

TEST(OptionChecks, FiniteRangeRefusesNanInfAndOutOfRange) {
  const CLI::Validator v = finite_range(0, 1000, true);
  EXPECT_EQ(check(v, "25"), "");
  EXPECT_EQ(check(v, "1000"), "");
  EXPECT_EQ(check(v, "1e3"), "");
  for (const char* bad : {"0", "-1", "1000.5", "1e13", "nan", "NaN", "-nan", "inf", "-inf", "1e400", "abc", "", "5m"})
    EXPECT_NE(check(v, bad), "") << bad;
  EXPECT_NE(check(v, "nan").find("not a finite number"), std::string::npos);
  EXPECT_EQ(check(finite_range(0, 1), "0"), "");
  EXPECT_EQ(finite_range(0, 1, true).get_description(), "in (0, 1]");
}

TEST(OptionChecks, IntegerRangeRefusesFractionsAndOutOfRange) {
  const CLI::Validator v = integer_range(-1, 256);
  for (const char* good : {"-1", "0", "256", "+7", "-0"}) EXPECT_EQ(check(v, good), "") << good;
  for (const char* bad : {"-2", "257", "1.5", "1e3", "nan", "", "99999999999999999999", "0x10", "010", " 5", "5 ", "--1"})
    EXPECT_NE(check(v, bad), "") << bad;
  // strtoull, which CLI11 uses, wraps "-1" and saturates an overflow: both are refused before it.
  const CLI::Validator seeds = integer_range(0, bounds::kMaxSeed);
  for (const char* bad : {"-1", "18446744073709551615", "9223372036854775808", "1e23"}) EXPECT_NE(check(seeds, bad), "") << bad;
  EXPECT_EQ(check(seeds, "9223372036854775807"), "");
  EXPECT_NE(check(v, "1e3").find("not an integer"), std::string::npos);
  EXPECT_NE(check(v, "010").find("leading zeros"), std::string::npos);
}

TEST(OptionChecks, DistortionNeedsFiveFiniteNumbers) {
  EXPECT_EQ(parse_distortion_option("-0.1 0.01 0 0.002 0")[3], 0.002);
  for (const char* bad : {"1 2 3 4", "1 2 3 nan 5", "1 2 3 4 inf", "1 2 3 4 5 6", "1 2 x 4 5"})
    EXPECT_THROW(parse_distortion_option(bad), CLI::ValidationError) << bad;
}

TEST(OptionChecks, MapOptionCombinationsAreBounded) {
  PipelineOptions p;
  MappingChoices c;
  c.max_memory_gb = 1e6;  // the machine's memory is another test's subject
  const auto run = [&](const std::string& feature_size = "192x128", const std::string& sim_precision = "fp32") {
    c.feature_size = feature_size;
    c.sim_feature_precision = sim_precision;
    check_map_options(p, c);
  };
  EXPECT_NO_THROW(run());
  p.map.occupancy.voxel_size = 0.01;  // 25 m clearing = 2500 voxels per ray: allowed
  EXPECT_NO_THROW(run());
  p.map.occupancy.max_clearing_range = 100;  // 10000 voxels per ray
  EXPECT_THROW(run(), CLI::ValidationError);
  p = {};
  p.fusion.max_depth = 1001 * p.map.occupancy.voxel_size * 4;
  EXPECT_THROW(run(), CLI::ValidationError);
  p = {};
  EXPECT_THROW(run("0x128"), CLI::ValidationError);
  EXPECT_THROW(run("5000x10"), CLI::ValidationError);
  EXPECT_THROW(run("1920x1200"), CLI::ValidationError);  // 4.7 GB of 512-d features
  EXPECT_THROW(run("1024x768"), CLI::ValidationError);    // 1.6 GB in fp32,
  EXPECT_NO_THROW(run("1024x768", "fp16"));               // 0.8 GB in fp16
  p.map.semantic.dim = 65536;                             // beyond any embedding
  EXPECT_THROW(run("8x8"), CLI::ValidationError);
}

// One scan at 0.01 m takes tens of GB: refused with the estimate, whatever the machine, unless
// --max-memory allows it; the defaults pass on any machine.
TEST(OptionChecks, MappingMemoryIsEstimatedAndBounded) {
  OccupancyParams occ;
  EXPECT_LT(estimate_scan_memory(occ, 512).total_bytes(), 0.5e9);
  EXPECT_NO_THROW(check_scan_memory(occ, 512, 0));  // 0: the machine's available memory
  occ.voxel_size = 0.01;
  EXPECT_GT(estimate_scan_memory(occ, 512).occupancy_bytes, 20e9);
  try {
    check_scan_memory(occ, 512, 16);
    ADD_FAILURE() << "0.01 m voxels fit in 16 GB?";
  } catch (const CLI::ValidationError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("--voxel-size 0.01"), std::string::npos) << m;
    EXPECT_NE(m.find("GB"), std::string::npos) << m;
    EXPECT_NE(m.find("16.0 GB of --max-memory"), std::string::npos) << m;
  }
  EXPECT_NO_THROW(check_scan_memory(occ, 512, 1000));
  occ.max_clearing_range = 2;  // clearing less of each ray is what makes small voxels possible
  EXPECT_LT(estimate_scan_memory(occ, 512).occupancy_bytes, 0.2e9);
  EXPECT_GT(available_memory_bytes(), 0.0);
}

TEST(OptionChecks, MemoryEstimateFollowsTheMeasurement) {
  EXPECT_NEAR(estimated_map_megabytes_per_100m(0.25, 16, 2), 46.0 + 23'500.0 * 72 / 1e6, 1e-9);
  EXPECT_GT(estimated_map_megabytes_per_100m(0.05, 512, 2), 1000.0);
}

}  // namespace
}  // namespace slamvdb::cli
