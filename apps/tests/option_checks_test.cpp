#include "option_checks.hpp"

#include <gtest/gtest.h>

#include "map_option_checks.hpp"

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
  for (const char* good : {"-1", "0", "256"}) EXPECT_EQ(check(v, good), "") << good;
  for (const char* bad : {"-2", "257", "1.5", "1e3", "nan", "", "99999999999999999999"}) EXPECT_NE(check(v, bad), "") << bad;
}

TEST(OptionChecks, DistortionNeedsFiveFiniteNumbers) {
  EXPECT_EQ(parse_distortion_option("-0.1 0.01 0 0.002 0")[3], 0.002);
  for (const char* bad : {"1 2 3 4", "1 2 3 nan 5", "1 2 3 4 inf", "1 2 3 4 5 6", "1 2 x 4 5"})
    EXPECT_THROW(parse_distortion_option(bad), CLI::ValidationError) << bad;
}

TEST(OptionChecks, MapOptionCombinationsAreBounded) {
  PipelineOptions p;
  const auto run = [&](const std::string& feature_size = "192x128", const std::string& sim_precision = "fp32") {
    check_map_options(p, "simulated", feature_size, sim_precision, "fp16", "", "/tmp/map.svdb");
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
  EXPECT_THROW(check_map_options(p, "simulated", "192x128", "fp32", "fp16", "", "/no/such/dir/map.svdb"), Error);
}

TEST(OptionChecks, MemoryEstimateFollowsTheMeasurement) {
  EXPECT_NEAR(estimated_map_megabytes_per_100m(0.25, 16, 2), 46.0 + 23'500.0 * 72 / 1e6, 1e-9);
  EXPECT_GT(estimated_map_megabytes_per_100m(0.05, 512, 2), 1000.0);
}

}  // namespace
}  // namespace slamvdb::cli
