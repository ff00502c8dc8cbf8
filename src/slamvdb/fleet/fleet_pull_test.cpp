// Pulling regions out of a fleet on a real PostgreSQL 15 + PostGIS server the test starts: the
// submaps come back voxel for voxel (odd values included) in the fleet frame, a region and a
// session filter select what PostGIS finds there, and a payload damaged in the database is an
// error naming the session, the submap and the row.
#include <gtest/gtest.h>

#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::patch_map;

class FleetPull : public ::testing::Test {
 protected:
  void SetUp() override { db_ = slamvdb::testing::fresh_test_database(server()); }
  static slamvdb::testing::PostgresServer& server() { return slamvdb::testing::shared_postgres_server(); }
  std::string sql(const std::string& query) const { return slamvdb::testing::psql_value(server(), query, db_); }
  std::string url() const { return server().url(db_); }
  static Eigen::AlignedBox3d box(double x0, double y0, double x1, double y1) {
    return {Vec3d(x0, y0, -1e3), Vec3d(x1, y1, 1e3)};
  }
  std::vector<PulledSubmap> pull(const Eigen::AlignedBox3d& b, std::vector<std::string> sessions = {}) const {
    std::vector<PulledSubmap> out;
    FleetDatabase(url()).pull({b, std::move(sessions)}, [&](PulledSubmap&& s) { out.push_back(std::move(s)); });
    return out;
  }
  std::string db_;
};

TEST_F(FleetPull, SubmapsComeBackVoxelForVoxelInTheFleetFrame) {
  const SemanticMap monday = slamvdb::testing::make_map(EmbeddingPrecision::kFloat16, 8, 1);
  const SemanticMap tuesday = slamvdb::testing::make_map(EmbeddingPrecision::kFloat16, 8, 2);
  const Pose T_fleet_tuesday = slamvdb::testing::make_pose(0.7, {30, -12, 0.5});
  FleetDatabase fleet(url());
  fleet.push_map(monday, {.session = "monday"});
  fleet.push_map(tuesday, {.session = "tuesday", .T_fleet_session = T_fleet_tuesday});

  std::vector<PulledSubmap> all = pull(box(-1e4, -1e4, 1e4, 1e4));
  ASSERT_EQ(all.size(), 4u);
  // Monday defines the fleet frame: its submaps come back as they were, bit for bit.
  SemanticMap back(monday.params(), monday.info());
  for (PulledSubmap& p : all) {
    EXPECT_EQ(p.info.id, &p - all.data());  // renumbered in pull order
    if (p.session != "monday") continue;
    SubmapInfo info = p.info;
    info.id = p.session_submap_id;
    back.add_finished_submap(info, std::move(p.voxels));
  }
  slamvdb::testing::expect_identical(monday, back);
  // Tuesday's anchors are carried into the fleet frame.
  for (const PulledSubmap& p : all) {
    if (p.session != "tuesday") continue;
    const Pose expected = T_fleet_tuesday * tuesday.submap_info(p.session_submap_id)->T_world_submap;
    EXPECT_TRUE(p.info.T_world_submap.isApprox(expected, 1e-12)) << p.session_submap_id;
  }
}

TEST_F(FleetPull, ARegionAndASessionFilterSelectWhatPostgisFindsThere) {
  Pose shifted = Pose::Identity();
  shifted.translation() = Vec3d(0, 50, 0);
  FleetDatabase fleet(url());
  fleet.push_map(patch_map(3, 40), {.session = "monday"});
  fleet.push_map(patch_map(3, 40), {.session = "tuesday", .T_fleet_session = shifted});
  const auto names = [](const std::vector<PulledSubmap>& pulled) {
    std::string out;
    for (const PulledSubmap& p : pulled) out += (out.empty() ? "" : ",") + p.session + ":" + std::to_string(p.session_submap_id);
    return out;
  };
  EXPECT_EQ(names(pull(box(102, 2, 105, 5))), "monday:1");
  EXPECT_EQ(names(pull(box(102, 2, 105, 55))), "monday:1,tuesday:1");
  EXPECT_EQ(names(pull(box(-10, -10, 250, 60), {"tuesday"})), "tuesday:0,tuesday:1,tuesday:2");
  EXPECT_EQ(names(pull(box(20, 20, 80, 40))), "");
  EXPECT_EQ(names(pull(box(-10, -10, 250, 60), {"friday"})), "");
  // Heights count too: the patches lie between z = 0 and 0.5 m.
  EXPECT_EQ(names(pull({Vec3d(102, 2, 5), Vec3d(105, 5, 9)})), "");
}

TEST_F(FleetPull, APayloadDamagedInTheDatabaseIsAnErrorNamingWhere) {
  FleetDatabase fleet(url());
  EXPECT_NE(slamvdb::testing::error_of([&] { pull(box(0, 0, 1, 1)); }).find("holds no fleet map"), std::string::npos);
  fleet.push_map(patch_map(2, 40), {.session = "monday"});
  sql("UPDATE slamvdb.occupancy SET log_odds = set_byte(log_odds, 3, (get_byte(log_odds, 3) + 1) % 256) "
      "WHERE submap = 1 AND bx = 0 AND by = 0 AND bz = 0");
  const std::string flipped = slamvdb::testing::error_of([&] { pull(box(-10, -10, 250, 10)); });
  EXPECT_NE(flipped.find("session 'monday' submap 1: CRC mismatch in occupancy block (0, 0, 0)"), std::string::npos)
      << flipped;
  EXPECT_EQ(pull(box(-10, -10, 50, 10)).size(), 1u);  // the undamaged submap still pulls

  sql("DELETE FROM slamvdb.semantics WHERE submap = 0");
  const std::string missing = slamvdb::testing::error_of([&] { pull(box(-10, -10, 50, 10)); });
  EXPECT_NE(missing.find("session 'monday' submap 0: submap 0 loaded with 0 semantic voxels but was saved with 800"),
            std::string::npos)
      << missing;
}

}  // namespace
}  // namespace slamvdb::fleet
