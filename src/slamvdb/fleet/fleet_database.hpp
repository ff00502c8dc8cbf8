#pragma once
// A connection to a fleet map: a PostgreSQL database with PostGIS that holds many sessions'
// submaps (docs/fleet-design.md). Connection strings are libpq's (URLs or key=value, with
// PGPASSFILE, PGHOST, ... from the environment), so credentials never need a command line.
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <functional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_pull.hpp"
#include "slamvdb/fleet/fleet_push.hpp"

namespace slamvdb::fleet {

// The schema version this build writes and reads. Older databases are migrated step by step;
// a newer one is refused (an older slamvdb must not write rows it does not understand).
inline constexpr int kFleetSchemaVersion = 3;  // 2: per-submap embedding caps; 3: shards
// The side of the tiles a fleet is split by across shards (metres, fleet frame; schema version 3).
inline constexpr double kFleetTileSide = 500.0;

// The fleet's catalog, without any payload (FleetDatabase::catalog): what `serve --db` answers on
// GET /api/info and /api/submaps.
struct CatalogSession {
  int64_t id = 0;
  std::string name, robot, source;
  std::optional<std::pair<double, double>> time_range;
  Pose T_fleet_session = Pose::Identity();
  std::size_t submaps = 0;
};
struct CatalogSubmap {
  std::string session;  // its session's name
  int id = 0;           // in its session
  Pose T_fleet_submap = Pose::Identity();  // T_fleet_session * T_world_submap
  std::optional<std::pair<double, double>> time_range;
  double path_length = 0;
  std::size_t blocks = 0, known_voxels = 0, occupied_voxels = 0, semantic_voxels = 0;
  int revision = 0;
  Eigen::AlignedBox3d bounds_fleet;  // its footprint and height range
};
struct FleetCatalog {
  std::vector<CatalogSession> sessions;  // by id (push order)
  std::vector<CatalogSubmap> submaps;    // by session, then id
  std::size_t submaps_without_session = 0;  // rows naming no session: left out, counted
};

struct SchemaCheck {
  int found_version = 0;  // 0: the database had no fleet schema
  int version = 0;        // after the check: always kFleetSchemaVersion
  bool created() const { return found_version == 0; }
  bool migrated() const { return found_version != 0 && found_version != version; }
};

// The fleet part's failures by their cause, so that a caller (serve --db) tells them apart by type,
// never by a message's text. Both are Errors (the CLI exits 1 on either, printing the message).
// - FleetDatabaseError: the database itself failed: it could not be reached, the connection was
//   lost, or a statement failed (a shard down, a lock or statement timeout, ...): asking again
//   later may succeed (serve answers 503).
// - FleetDataError: the database answered, but what it holds is damaged or foreign (a payload's
//   checksum, a pose that is not rigid, a NULL where a value belongs, no fleet map in it): asking
//   again gives the same (serve answers 500 with the reason).
// A question that does not fit the fleet (a query set of another space, ...) stays a plain Error.
class FleetDatabaseError : public Error {
 public:
  enum class Kind { kUnreachable, kConnectionLost, kStatementFailed };
  FleetDatabaseError(Kind kind, const std::string& message) : Error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};
class FleetDataError : public Error {
 public:
  using Error::Error;
};

// A connection string with any password removed, for messages and logs.
std::string redact_connection_url(std::string_view url);

class FleetDatabase {
 public:
  // Connects; throws FleetDatabaseError (kUnreachable) naming the (redacted) connection string and
  // the server's reason.
  explicit FleetDatabase(const std::string& url);
  ~FleetDatabase();
  FleetDatabase(FleetDatabase&&) noexcept;
  FleetDatabase& operator=(FleetDatabase&&) noexcept;

  // Creates PostGIS and the fleet schema in an empty database, migrates an older schema, leaves
  // a current one alone; refuses a newer one and a damaged one (Error saying which and why).
  // Safe when several robots call it at once: the work is serialised by an advisory lock.
  SchemaCheck ensure_schema();
  // The fleet schema version of the database, 0 when it has none (nothing is changed).
  int schema_version();

  // Pushes every submap of `map` as the session `options.session`: the schema first if the
  // database has none, then the session row, then one transaction per submap, so a crash or a
  // killed server leaves whole submaps only and a repeated push completes the rest. Idempotent:
  // a submap already there with the same payload is not written again; a new anchor (a loop
  // correction, an alignment) rewrites its catalog row and footprint only. A map whose embedding
  // space, voxel size, ontology or occupancy clamping differ from the fleet's is refused before
  // anything is written (Error naming the entry and both values).
  PushReport push_map(const SemanticMap& map, const PushOptions& options);
  // The same refusal as push_map's, from a map's parameters alone (a map file's summary), so a
  // command refuses before it reads the voxels; creates the schema if there is none.
  void check_map(const MapParams& params, const MapInfo& info);

  // The fleet's parameters and embedding space (Error when nothing was pushed yet).
  FleetDefinition definition();
  // The submaps whose footprint meets the region, session by session in push order, each read
  // in one snapshot and checked row by row as a map file's are (CRCs, values, counts: a payload
  // damaged in the database is an Error naming the session, submap and row), handed to `sink`
  // one at a time (memory: one submap).
  PullReport pull(const PullRequest& request, const std::function<void(PulledSubmap&&)>& sink);
  // The region as one map in memory (the fleet's parameters; memory: the region, not the fleet),
  // for questions asked of a region without a file: query and classify --db.
  SemanticMap pull_map(const PullRequest& request);

  // Every session and submap of the catalog, in one snapshot (no payload is read).
  FleetCatalog catalog();
  // The semantic voxels of every submap of the catalog: one sum, no row read into this process.
  std::size_t semantic_voxels();

  // The catalog rows of the region's submaps (request.only ignored): keys, boxes, summaries; no
  // payload is read. In pull's order.
  std::vector<RegionSubmap> region_catalog(const PullRequest& request);

  // Adds a shard server to this fleet (docs/fleet-design.md, "Scale out"): `shard_url` names an
  // empty database on it where PostGIS is installed; its tables are created there and attached to
  // this coordinator through postgres_fdw. An empty coordinator becomes a sharded fleet (its
  // submaps and payload rows live only on shards from then on); a fleet that already holds submaps
  // in its own tables is refused. New tiles go to the newest shard; returns the shard's id.
  // `name`: [a-z][a-z0-9_]*, at most 40 characters, unique in the fleet.
  int add_shard(const std::string& name, const std::string& shard_url);
  // The shards of the fleet, id and name in id order (empty: the fleet is on this server only).
  std::vector<std::pair<int, std::string>> shards();

  const std::string& display_url() const { return display_url_; }

 private:
  friend class FleetPushSession;
  struct Connection;
  std::unique_ptr<Connection> connection_;
  std::string display_url_;
};

}  // namespace slamvdb::fleet
