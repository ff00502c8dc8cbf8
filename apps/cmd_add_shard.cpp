// `slamvdb add-shard`: one more PostgreSQL server for a fleet map (issue 24, "Scale out"): an
// empty database on it becomes a shard that the coordinator reaches through postgres_fdw; new
// tiles go to it from then on (docs/fleet-design.md).
#include <fmt/format.h>

#include <memory>

#include "command_registry.hpp"
#include "slamvdb/fleet/fleet_database.hpp"

namespace slamvdb::cli::cmd_add_shard {
namespace {

struct Options {
  std::string db, shard_db, name;
};

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "add-shard", "Add a PostgreSQL server to a fleet map: an empty database there becomes a shard (postgres_fdw) "
                   "that takes the fleet's new tiles; an empty fleet database becomes a sharded fleet");
  cmd->add_option("--db", opt->db, "The fleet's coordinator database (libpq connection string)")->required();
  cmd->add_option("--shard-db", opt->shard_db,
                  "An empty database on the new server where PostGIS is installed (libpq connection string, as the "
                  "coordinator's server reaches it: host, port, dbname, user)")
      ->required();
  cmd->add_option("--name", opt->name, "The shard's name in the fleet: a-z, 0-9, _ (at most 40)")->required();
  cmd->callback([opt] {
    fleet::FleetDatabase fleet(opt->db);
    const int id = fleet.add_shard(opt->name, opt->shard_db);
    fmt::print("shard      '{}' (id {}) added to {}; new tiles go to it\n", opt->name, id, fleet.display_url());
    for (const auto& [shard, name] : fleet.shards()) fmt::print("shards     {} {}\n", shard, name);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_add_shard
