// The fleet schema on a real PostgreSQL 15 + PostGIS server started by the test (no mock): created
// once in an empty database, left alone after, created by exactly one of several robots starting at
// once, and refused (untouched) when newer or damaged. Checked with psql, an independent client.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_schema.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::PostgresServer;

class FleetSchema : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { server_ = &slamvdb::testing::shared_postgres_server(); }
  std::string fresh_database() { return slamvdb::testing::fresh_test_database(*server_); }
  static std::string sql(const std::string& query, const std::string& database) {
    return slamvdb::testing::psql_value(*server_, query, database);
  }
  static inline PostgresServer* server_ = nullptr;
};

TEST_F(FleetSchema, AnEmptyDatabaseGetsPostgisAndTheSchemaOnceAndIsLeftAloneAfter) {
  const std::string db = fresh_database();
  FleetDatabase fleet(server_->url(db));
  EXPECT_EQ(fleet.schema_version(), 0);
  const SchemaCheck first = fleet.ensure_schema();
  EXPECT_TRUE(first.created());
  EXPECT_EQ(first.version, kFleetSchemaVersion);
  EXPECT_EQ(fleet.schema_version(), kFleetSchemaVersion);
  EXPECT_EQ(sql("SELECT count(*) FROM pg_extension WHERE extname = 'postgis'", db), "1");
  EXPECT_EQ(sql("SELECT string_agg(table_name, ',' ORDER BY table_name) FROM information_schema.tables "
                "WHERE table_schema = 'slamvdb'",
                db),
            "fleet,occupancy,schema_info,semantics,sessions,shards,submap_homes,submaps,tiles");
  // The region look-up's index: a GiST index on the footprints.
  EXPECT_EQ(sql("SELECT count(*) FROM pg_indexes WHERE schemaname = 'slamvdb' AND tablename = 'submaps' "
                "AND indexdef LIKE '%USING gist (footprint)%'",
                db),
            "1");
  // Compressed occupancy blobs are not compressed again by TOAST.
  EXPECT_EQ(sql("SELECT attstorage FROM pg_attribute WHERE attrelid = 'slamvdb.occupancy'::regclass "
                "AND attname = 'log_odds'",
                db),
            "e");
  // Nor embeddings, where pglz gains nothing (version 3); the small key and count blobs compress.
  EXPECT_EQ(sql("SELECT string_agg(attname || '=' || attstorage::text, ',' ORDER BY attname) FROM pg_attribute "
                "WHERE attrelid = 'slamvdb.semantics'::regclass AND atttypid = 'bytea'::regtype",
                db),
            "counts=x,embeddings=e,keys=x,stats=x");
  // A second check (another process, later) changes nothing.
  sql("INSERT INTO slamvdb.sessions(name, t_fleet_session) VALUES ('monday', array_fill(0::float8, ARRAY[16]))", db);
  const SchemaCheck second = FleetDatabase(server_->url(db)).ensure_schema();
  EXPECT_FALSE(second.created());
  EXPECT_FALSE(second.migrated());
  EXPECT_EQ(second.found_version, kFleetSchemaVersion);
  EXPECT_EQ(sql("SELECT name FROM slamvdb.sessions", db), "monday");
}

TEST_F(FleetSchema, RobotsStartingAtOnceAllSucceedAndOneCreatesTheSchema) {
  const std::string db = fresh_database();
  constexpr int kRobots = 4;
  std::atomic<int> created{0}, failed{0}, ready{0};
  std::vector<std::thread> robots;
  for (int i = 0; i < kRobots; ++i)
    robots.emplace_back([&] {
      try {
        FleetDatabase fleet(server_->url(db));
        ++ready;
        while (ready < kRobots) std::this_thread::yield();  // all connected, then all at once
        created += fleet.ensure_schema().created();
      } catch (const std::exception&) {
        ++failed;
      }
    });
  for (std::thread& t : robots) t.join();
  EXPECT_EQ(failed, 0);
  EXPECT_EQ(created, 1);
  EXPECT_EQ(sql("SELECT version FROM slamvdb.schema_info", db), std::to_string(kFleetSchemaVersion));
}

TEST_F(FleetSchema, AVersionOneDatabaseIsMigratedKeepingItsRowsWithoutSummaries) {
  const std::string db = fresh_database();
  // A database as a version-1 slamvdb left it: its step's SQL, its version row, one submap.
  sql("CREATE EXTENSION postgis", db);
  sql(fleet_migrations()[0], db);
  sql("INSERT INTO slamvdb.schema_info(version) VALUES (1)", db);
  sql("INSERT INTO slamvdb.sessions(name, t_fleet_session) VALUES ('old', '{1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1}')", db);
  sql("INSERT INTO slamvdb.submaps(session, submap, t_world_submap, path_length, footprint, z_min, z_max, blocks, "
      "known_voxels, occupied_voxels, semantic_voxels, payload_format, payload_crc, payload_bytes) SELECT id, 4, "
      "t_fleet_session, 1, ST_MakeEnvelope(0, 0, 1, 1, 0), 0, 1, 0, 0, 0, 0, 3, 0, 0 FROM slamvdb.sessions", db);
  FleetDatabase fleet(server_->url(db));
  EXPECT_EQ(fleet.schema_version(), 1);
  const SchemaCheck check = fleet.ensure_schema();
  EXPECT_TRUE(check.migrated());
  EXPECT_EQ(check.found_version, 1);
  EXPECT_EQ(fleet.schema_version(), kFleetSchemaVersion);
  EXPECT_EQ(sql("SELECT version FROM slamvdb.schema_info", db), std::to_string(kFleetSchemaVersion));
  // Version 3: the row is on this server's own shard (0), its home tile and the tile's extent
  // come from its footprint, so a region query still finds it.
  EXPECT_EQ(sql("SELECT shard FROM slamvdb.submaps", db), "0");
  EXPECT_EQ(sql("SELECT submap, tile_x, tile_y FROM slamvdb.submap_homes", db), "4|0|0");
  EXPECT_EQ(sql("SELECT tile_x, tile_y, shard, x_min, y_min, x_max, y_max FROM slamvdb.tiles", db), "0|0|0|0|0|1|1");
  // The old row is kept, without a summary (so a query always reads it).
  EXPECT_EQ(sql("SELECT submap, embedding_radius IS NULL, embedding_centroid IS NULL FROM slamvdb.submaps", db), "4|t|t");
  EXPECT_FALSE(fleet.ensure_schema().migrated());  // a second look changes nothing
  EXPECT_THROW(sql("UPDATE slamvdb.submaps SET embedding_radius = 0.1", db), std::runtime_error);  // no centroid
}

TEST_F(FleetSchema, ANewerSchemaIsRefusedAndLeftUntouched) {
  const std::string db = fresh_database();
  FleetDatabase(server_->url(db)).ensure_schema();
  sql("UPDATE slamvdb.schema_info SET version = 7", db);
  FleetDatabase fleet(server_->url(db));
  EXPECT_EQ(fleet.schema_version(), 7);
  const std::string error = slamvdb::testing::error_of([&] { fleet.ensure_schema(); });
  EXPECT_NE(error.find("schema version 7, newer than this slamvdb's " + std::to_string(kFleetSchemaVersion)),
            std::string::npos)
      << error;
  EXPECT_EQ(sql("SELECT version FROM slamvdb.schema_info", db), "7");
}

TEST_F(FleetSchema, ADamagedSchemaIsRefusedAndLeftUntouched) {
  const std::string db = fresh_database();
  sql("CREATE SCHEMA slamvdb; CREATE TABLE slamvdb.mine(x int)", db);
  const std::string no_table = slamvdb::testing::error_of([&] { FleetDatabase(server_->url(db)).ensure_schema(); });
  EXPECT_NE(no_table.find("without its version table"), std::string::npos) << no_table;
  EXPECT_EQ(sql("SELECT count(*) FROM information_schema.tables WHERE table_schema = 'slamvdb'", db), "1");

  sql("DROP SCHEMA slamvdb CASCADE", db);
  FleetDatabase(server_->url(db)).ensure_schema();
  sql("DELETE FROM slamvdb.schema_info", db);
  const std::string no_row = slamvdb::testing::error_of([&] { FleetDatabase(server_->url(db)).ensure_schema(); });
  EXPECT_NE(no_row.find("holds 0 rows"), std::string::npos) << no_row;
}

TEST_F(FleetSchema, ConnectionErrorsNameTheServerButNeverThePassword) {
  const std::string url = "postgresql://robot:s3cret@/fleet?host=" + (std::filesystem::temp_directory_path() / "no-server-here").string() + "&port=5432";
  const std::string error = slamvdb::testing::error_of([&] { FleetDatabase fleet(url); });
  EXPECT_NE(error.find("cannot connect to the fleet database postgresql://robot:***@/fleet"), std::string::npos)
      << error;
  EXPECT_NE(error.find("no-server-here"), std::string::npos) << error;
  EXPECT_EQ(error.find("s3cret"), std::string::npos) << error;

  EXPECT_EQ(redact_connection_url("host=a password=x dbname=f"), "host=a password=*** dbname=f");
  EXPECT_EQ(redact_connection_url("host=a password='x y' dbname=f"), "host=a password=*** dbname=f");
  EXPECT_EQ(redact_connection_url("postgres://u:p@h:5/db?password=q&sslmode=require"),
            "postgres://u:***@h:5/db?password=***&sslmode=require");
  EXPECT_EQ(redact_connection_url("postgresql:///db?host=/tmp"), "postgresql:///db?host=/tmp");
}

}  // namespace
}  // namespace slamvdb::fleet
