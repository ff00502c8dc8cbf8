// The catalog rows decoded from PostgreSQL's text (fleet_catalog_rows.hpp), without a database:
// the rows of the fuzz seeds are accepted with their values, and each kind of damage is an Error
// naming the row and the column (never another exception, a NaN or an empty box).
#include <gtest/gtest.h>

#include <functional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_catalog_rows.hpp"

namespace slamvdb::fleet {
namespace {

TextRow session_row(std::string_view id, std::optional<std::string_view> begin = "0") {
  return {id, "monday", "robot-a", "SIMULATED drive", begin, "12.5", "{0,-1,0,3,1,0,0,4,0,0,1,0,0,0,0,1}"};
}
TextRow submap_row(std::string_view session, std::string_view z_max = "1.5", std::string_view blocks = "4") {
  return {session, "1", "{1,0,0,100,0,1,0,0,0,0,1,0,0,0,0,1}", std::nullopt, std::nullopt, "12.5", blocks, "4096",
          "812", "800", "2", "100", "0", "-0.5", "110", "10", z_max};
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(FleetCatalogRows, DecodesTheCatalogInTheFleetFrameAndCountsSubmapsOfNoSession) {
  const FleetCatalog c = catalog_of({session_row("1")}, {submap_row("1"), submap_row("7")});
  ASSERT_EQ(c.sessions.size(), 1u);
  EXPECT_EQ(c.sessions[0].name, "monday");
  EXPECT_EQ(c.sessions[0].submaps, 1u);
  ASSERT_TRUE(c.sessions[0].time_range);
  EXPECT_EQ(c.sessions[0].time_range->second, 12.5);
  ASSERT_EQ(c.submaps.size(), 1u);
  EXPECT_EQ(c.submaps_without_session, 1u);
  const CatalogSubmap& m = c.submaps[0];
  EXPECT_EQ(m.session, "monday");
  EXPECT_FALSE(m.time_range);
  EXPECT_EQ(m.revision, 2);
  EXPECT_EQ(m.semantic_voxels, 800u);
  // T_fleet_session (a quarter turn, then (3, 4)) * T_world_submap ((100, 0, 0)): (3, 104, 0).
  EXPECT_TRUE(m.T_fleet_submap.translation().isApprox(Vec3d(3, 104, 0))) << m.T_fleet_submap.translation().transpose();
  EXPECT_EQ(m.bounds_fleet.max(), Vec3d(110, 10, 1.5));
}

TEST(FleetCatalogRows, DamagedRowsAreErrorsNamingRowAndColumn) {
  EXPECT_NE(error_of([] { catalog_of({session_row("x1")}, {}); }).find("id ('x1') is not an integer"), std::string::npos);
  EXPECT_NE(error_of([] { catalog_of({session_row("1"), session_row("1")}, {}); }).find("given twice"), std::string::npos);
  EXPECT_NE(error_of([] { catalog_of({session_row("1", "NaN")}, {}); }).find("time_begin ('NaN') is not a finite"),
            std::string::npos);
  EXPECT_NE(error_of([] { catalog_of({session_row("1")}, {submap_row("1", "-2")}); }).find("catalog submap row 1: its box"),
            std::string::npos);
  EXPECT_NE(error_of([] { catalog_of({session_row("1")}, {submap_row("1", "1.5", "-4")}); }).find("blocks"),
            std::string::npos);
  TextRow nulled = submap_row("1");
  nulled[5] = std::nullopt;
  EXPECT_NE(error_of([&] { catalog_of({session_row("1")}, {nulled}); }).find("path_length is NULL"), std::string::npos);
  TextRow short_row = submap_row("1");
  short_row.pop_back();
  EXPECT_NE(error_of([&] { catalog_of({session_row("1")}, {short_row}); }).find("16 columns, expected 17"),
            std::string::npos);
  TextRow sheared = session_row("1");
  sheared[6] = "{1,0.5,0,0,0,1,0,0,0,0,1,0,0,0,0,1}";
  EXPECT_NE(error_of([&] { catalog_of({sheared}, {}); }).find("not a rigid transform"), std::string::npos);
}

TEST(FleetCatalogRows, RegionRowsKeepTheirSummaryOrRefuseADamagedOne) {
  const TextRow with_cap = {"1", "0", "0", "0", "-0.5", "10", "10", "1.5", "{0.70710677,0,0,0.70710677}", "0.32", "800"};
  const RegionSubmap s = region_submap_of(with_cap);
  EXPECT_EQ(s.key, (FleetSubmapKey{1, 0}));
  ASSERT_TRUE(s.cap);
  EXPECT_EQ(s.cap->centroid.size(), 4u);
  EXPECT_EQ(s.cap->radius, 0.32);
  TextRow without = with_cap;
  without[8] = without[9] = std::nullopt;
  EXPECT_FALSE(region_submap_of(without).cap);
  TextRow zero = with_cap;
  zero[8] = "{0,0,0,0}";
  EXPECT_NE(error_of([&] { region_submap_of(zero); }).find("a centroid of no length"), std::string::npos);
  TextRow centroid_null = with_cap;
  centroid_null[8] = std::nullopt;
  EXPECT_NE(error_of([&] { region_submap_of(centroid_null); }).find("embedding_centroid is NULL"), std::string::npos);
}

}  // namespace
}  // namespace slamvdb::fleet
