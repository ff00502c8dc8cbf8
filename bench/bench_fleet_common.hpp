#pragma once
// What the fleet benchmarks share (bench_fleet.cpp: one server; bench_fleet_scale.cpp: a sharded
// fleet): the reference a push is measured against.
#include <filesystem>
#include <string>

#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::bench {

// The reference for a push: the payload rows the push wrote into `database` (a fleet on one
// server, or one shard of a sharded fleet), exported by COPY TO in COPY's text form (hex bytea, as
// push streams them) into files in the server's own directory, then loaded by psql's \copy over
// the same socket into tables like the fleet's (primary keys, STORAGE EXTERNAL; no catalog rows, no
// foreign keys, no encoding, no CRC). Only load() is the measured part.
class FleetCopyReference {
 public:
  FleetCopyReference(const testing::PostgresServer& server, std::string database)
      : server_(server), database_(std::move(database)) {
    const std::filesystem::path dir = server_.data().parent_path();  // the server's own, writable by it
    const std::string occupancy = (dir / (database_ + "_occupancy.copy")).string(),
                      semantics = (dir / (database_ + "_semantics.copy")).string();
    psql("COPY slamvdb.occupancy TO '" + occupancy + "'; COPY slamvdb.semantics TO '" + semantics + "'");
    psql("DROP TABLE IF EXISTS ref_occupancy, ref_semantics; "
         "CREATE TABLE ref_occupancy (LIKE slamvdb.occupancy INCLUDING ALL); "
         "CREATE TABLE ref_semantics (LIKE slamvdb.semantics INCLUDING ALL)");
    load_command_ = std::string(testing::PostgresServer::kBinDir) + "/psql -X -q -v ON_ERROR_STOP=1 -d " +
                    testing::shell_quote(server_.url(database_)) + " -c " +
                    testing::shell_quote("\\copy ref_occupancy FROM '" + occupancy + "'") + " -c " +
                    testing::shell_quote("\\copy ref_semantics FROM '" + semantics + "'");
  }
  // Empties the reference tables (not part of the measurement).
  void truncate() const { psql("TRUNCATE ref_occupancy, ref_semantics"); }
  // The measured part: both files loaded; exit code and psql's output.
  testing::CommandResult load() const { return testing::run_command(load_command_, 600); }

 private:
  void psql(const std::string& sql) const { server_.psql(sql, database_); }
  const testing::PostgresServer& server_;
  std::string database_, load_command_;
};

}  // namespace slamvdb::bench
