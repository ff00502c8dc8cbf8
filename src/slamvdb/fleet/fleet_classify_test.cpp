// classify --db tile by tile (fleet/fleet_classify.hpp) on a real PostgreSQL 15 + PostGIS server:
// the cells, classes and scores equal classify on the pulled region exactly, for a box, a
// cylinder and a ball, with tiles small enough that one tile's submaps are all memory holds; a
// submap whose box meets the region's bounding box but not its shape is never read.
#include <gtest/gtest.h>

#include "slamvdb/fleet/fleet_classify.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::fleet {
namespace {

QuerySet two_classes() {
  QuerySet q;
  q.model_id = "fleet-test-space";
  q.names = {"near-edge", "far-edge"};
  q.vectors = QueryMatrix::Zero(2, 4);
  q.vectors(0, 3) = 1;
  q.vectors(1, 1) = 1;
  return q;
}

QueryRegion box(double x0, double y0, double x1, double y1) {
  return {Eigen::AlignedBox3d(Vec3d(x0, y0, -1), Vec3d(x1, y1, 2)), std::nullopt};
}
QueryRegion near(double x, double y, double r, bool horizontal) {
  return {std::nullopt, QueryRegion::Near{Vec3d(x, y, 0.2), horizontal, r}};
}

void expect_same_cells(const std::vector<ClassifiedCell>& a, std::vector<ClassifiedCell> b) {
  sort_by_cell(b);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].cell, b[i].cell) << i;
    EXPECT_EQ(a[i].match.class_index, b[i].match.class_index) << i;
    EXPECT_EQ(a[i].match.score, b[i].match.score) << i;
    EXPECT_EQ(a[i].match.margin, b[i].match.margin) << i;
    EXPECT_EQ(a[i].count, b[i].count) << i;
    EXPECT_EQ(a[i].confidence, b[i].confidence) << i;
  }
}

TEST(FleetClassify, TileByTileEqualsThePulledRegionAndReadsOnlyTheRegionsShape) {
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string db = slamvdb::testing::fresh_test_database(server);
  FleetDatabase fleet(server.url(db));
  Pose north = Pose::Identity();
  north.translation() = Vec3d(3, 4, 0);  // overlapping the first session: cells with entries of both
  fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "monday"});
  fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "tuesday", .T_fleet_session = north});
  const QuerySet queries = two_classes();
  for (const QueryRegion& region : {box(-5, -5, 240, 20), box(95, -5, 140, 20), near(105, 7, 6, true),
                                    near(105, 7, 4, false)}) {
    FleetClassifyOptions options;
    options.tile_side = 2.5;  // tiles of 10 x 10 cells: a patch spans several, each read once per tile
    const FleetClassification tiled = classify_fleet_region(fleet, region, queries, options);
    const std::vector<ClassifiedCell> whole =
        classify_region(fleet.pull_map({region.bounds(), {}}), queries, region);
    EXPECT_GT(whole.size(), 10u);
    expect_same_cells(tiled.cells, whole);
    EXPECT_GT(tiled.tiles, 1u);
    EXPECT_GT(tiled.reads, tiled.submaps_read);  // patches met several tiles
  }
  // The whole row of six patches: memory held the two overlapping patches of one place at most.
  const FleetClassification all = classify_fleet_region(fleet, box(-5, -5, 240, 20), queries, {.tile_side = 5});
  EXPECT_EQ(all.submaps_read, 6u);
  EXPECT_EQ(all.peak_submaps_in_memory, 2u);
  // A disc whose bounding square meets monday's patch at (100..110, 0..10) only past its corner:
  // PostGIS returns it, the shape test does not read it; tuesday's (103..113, 4..14) is read.
  const FleetClassification corner = classify_fleet_region(fleet, near(119.5, 19.5, 10, true), queries);
  EXPECT_EQ(corner.submaps_in_region, 2u);
  EXPECT_EQ(corner.submaps_read, 1u);
  EXPECT_EQ(corner.submaps_skipped, 1u);
  expect_same_cells(corner.cells, classify_region(fleet.pull_map({near(119.5, 19.5, 10, true).bounds(), {}}), queries,
                                                  near(119.5, 19.5, 10, true)));
}

}  // namespace
}  // namespace slamvdb::fleet
