#pragma once
// Where `query` and `classify` read the map: a map file (the positional argument), or a region of
// a fleet map (--db URL with --bbox or --near/--radius, and --session): PostGIS selects the
// region's submaps and only those are read, so the answers equal those on the pulled file.
// --session also restricts a map file to those sessions' submaps (session_option.hpp).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "region_options.hpp"
#include "session_option.hpp"
#include "slamvdb/fleet/fleet_classify.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_search.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {

struct MapSourceOptions {
  std::string map, db;
  std::vector<std::string> sessions;

  void add_to(CLI::App* cmd) {
    cmd->add_option("map", map, "Map file (.svdb); or --db")->check(CLI::ExistingFile);
    cmd->add_option("--db", db,
                    "Ask a fleet map instead of a file: a libpq connection string (PostgreSQL + PostGIS, see "
                    "`push`); needs a region (--bbox or --near with --radius), whose submaps alone are read");
    add_session_option(cmd, sessions,
                       "Only these sessions' submaps, of the map file or with --db of the fleet map (repeatable; "
                       "default: every session)");
  }
  // Usage checks before any work (exit 2).
  void check(const RegionOptions& region) const {
    if (map.empty() == db.empty()) usage_error("give a map file or --db URL (one of the two)");
    if (!db.empty() && !region.given())
      usage_error("--db needs a region (--bbox, or --near with --radius): a fleet map is not read whole");
  }
  // For messages and titles: the file, or the fleet's URL without its password.
  std::string name() const { return db.empty() ? map : fleet::redact_connection_url(db); }
  // With --db, for a similarity search: the region's submaps that can hold the answer only
  // (fleet/fleet_search.hpp; the search on the returned map answers as on the whole region).
  // `build_query` gets a map without submaps in the fleet's space; its answer goes to *query.
  // Prints how many submaps were read and skipped.
  SemanticMap read_for_search(const std::optional<QueryRegion>& region,
                              const std::function<Eigen::VectorXf(const SemanticMap&)>& build_query,
                              const SearchOptions& options, Eigen::VectorXf* query) const {
    fleet::FleetDatabase fleet(db);
    const fleet::FleetDefinition definition = fleet.definition();
    *query = build_query(SemanticMap(definition.params, definition.info));
    fleet::PrunedRegion pruned = fleet::pull_for_search(
        fleet, {region->bounds(), sessions},
        std::span<const float>(query->data(), static_cast<std::size_t>(query->size())), options);
    const fleet::PrunedSearchReport& r = pruned.report;
    fmt::print("fleet: {} submaps in the region, {} read, {} skipped by their summaries ({} of {} groups), {:.3f} s\n",
               r.submaps_in_region, r.submaps_scored, r.submaps_skipped, r.groups_skipped, r.groups, r.seconds);
    return std::move(pruned.map);
  }
  // With --db, classify: the region tile by tile, one tile's submaps in memory at a time
  // (fleet/fleet_classify.hpp; the cells of classify on the pulled region). Prints what was read.
  std::vector<ClassifiedCell> classify_fleet(const QueryRegion& region, const QuerySet& queries,
                                             const ClassifyOptions& options, ModelIdCheck model_check) const {
    fleet::FleetDatabase fleet(db);
    fleet::FleetClassification c = fleet::classify_fleet_region(fleet, region, queries, {options, model_check, sessions});
    fmt::print("fleet: {} submaps in the region, {} read ({} reads over {} tiles, at most {} submaps in memory), {} "
               "skipped (outside the region or without semantics), {:.3f} s\n",
               c.submaps_in_region, c.submaps_read, c.reads, c.tiles, c.peak_submaps_in_memory, c.submaps_skipped,
               c.seconds);
    return std::move(c.cells);
  }
  SemanticMap read(const std::optional<QueryRegion>& region) const {
    if (db.empty()) return load_map_of_sessions(map, sessions);
    fleet::FleetDatabase fleet(db);
    return fleet.pull_map({region->bounds(), sessions});
  }
};

}  // namespace slamvdb::cli
