#include "slamvdb/localization/scan_context.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace slamvdb::localization {
namespace {

// A random "place": boxes of random heights scattered around the sensor, plus ground.
std::vector<Vec3d> random_place(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3d> pts;
  for (int b = 0; b < 40; ++b) {
    const Vec3d c(60.0 * u(rng), 60.0 * u(rng), 0.0);
    const double h = 2.0 + 4.0 * (u(rng) + 1.0);
    for (double z = -1.5; z < h; z += 0.3)
      for (int k = 0; k < 8; ++k) pts.push_back(c + Vec3d(u(rng), u(rng), z));
  }
  for (int k = 0; k < 3000; ++k) pts.emplace_back(70.0 * u(rng), 70.0 * u(rng), -1.5);
  return pts;
}

std::vector<Vec3d> rotated(const std::vector<Vec3d>& pts, double yaw) {
  const Eigen::AngleAxisd R(yaw, Vec3d::UnitZ());
  std::vector<Vec3d> out;
  for (const Vec3d& p : pts) out.push_back(R * p);
  return out;
}

TEST(ScanContext, RecoversTheYawBetweenTwoViewsOfAPlace) {
  const ScanContextConfig config;
  const auto place = random_place(1);
  const double yaw = 12 * 2.0 * std::numbers::pi / config.sectors;  // whole sectors: bins map one to one
  // The query sees the place turned: points of the candidate frame p appear at R^-1 p.
  const ScanContext candidate = make_scan_context(place, config);
  const ScanContext query = make_scan_context(rotated(place, -yaw), config);
  const ScanContextMatch m = compare_scan_contexts(query, candidate, config);
  EXPECT_LT(m.distance, 0.05);
  EXPECT_NEAR(m.yaw, yaw, 2.0 * std::numbers::pi / config.sectors);
  const ScanContextMatch other = compare_scan_contexts(query, make_scan_context(random_place(2), config), config);
  EXPECT_GT(other.distance, 0.2);
  // Between sectors the yaw is still found to within a sector.
  const ScanContextMatch between =
      compare_scan_contexts(make_scan_context(rotated(place, -1.2), config), candidate, config);
  EXPECT_NEAR(between.yaw, 1.2, 2.0 * std::numbers::pi / config.sectors);
  EXPECT_LT(between.distance, other.distance);
}

TEST(ScanContext, DatabaseFindsTheRevisitedPlaceAmongOthers) {
  ScanContextDatabase db;
  for (unsigned s = 0; s < 30; ++s) db.add(make_scan_context(random_place(100 + s), db.config()));
  const ScanContext query = make_scan_context(rotated(random_place(117), 0.5), db.config());
  const auto found = db.query(query, db.size(), 10, 0.3);
  ASSERT_FALSE(found.empty());
  EXPECT_EQ(found.front().index, 17u);
  EXPECT_TRUE(db.query(query, 17, 10, 0.3).empty() || db.query(query, 17, 10, 0.3).front().index != 17u)
      << "entries past eligible_end are never returned";
  EXPECT_EQ(make_scan_context({}, db.config()).descriptor.sum(), 0.0f);
}

}  // namespace
}  // namespace slamvdb::localization
