#include "slamvdb/fleet/fleet_schema.hpp"

#include <array>

#include "slamvdb/fleet/fleet_database.hpp"

namespace slamvdb::fleet {
namespace {

// Version 1 (docs/fleet-design.md, "Schema", says why each choice):
// - one fleet frame for every session (metres, SRID 0: a local frame, not a geographic one);
// - poses as 16 doubles, row-major 4x4, named T_a_b as everywhere in slamvdb;
// - a submap's footprint is its world bounds' box in the fleet frame (a polygon with a GiST
//   index) plus its height range; corrections rewrite anchors and footprints, never payloads;
// - the payload rows are the map file's own (store format 3): occupancy blocks (compressed by
//   slamvdb, so STORAGE EXTERNAL: TOAST must not try to compress them again) and semantic chunks.
constexpr const char* kVersion1 = R"sql(
CREATE SCHEMA slamvdb;
CREATE TABLE slamvdb.schema_info(
  version integer NOT NULL,
  single boolean PRIMARY KEY DEFAULT true CHECK (single));
CREATE TABLE slamvdb.fleet(
  single boolean PRIMARY KEY DEFAULT true CHECK (single),
  voxel_size double precision NOT NULL CHECK (voxel_size > 0),
  semantic_dim integer NOT NULL CHECK (semantic_dim > 0),
  model_id text NOT NULL,
  ontology text NOT NULL,
  params jsonb NOT NULL,  -- the map file's meta entries that every pushed map must share
  colour_basis text);
CREATE TABLE slamvdb.sessions(
  id bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  name text NOT NULL UNIQUE,
  robot text NOT NULL DEFAULT '',
  source text NOT NULL DEFAULT '',
  time_begin double precision,
  time_end double precision,
  t_fleet_session double precision[] NOT NULL CHECK (cardinality(t_fleet_session) = 16),
  pushed_at timestamptz NOT NULL DEFAULT now());
CREATE TABLE slamvdb.submaps(
  session bigint NOT NULL REFERENCES slamvdb.sessions(id) ON DELETE CASCADE,
  submap integer NOT NULL,
  t_world_submap double precision[] NOT NULL CHECK (cardinality(t_world_submap) = 16),
  time_begin double precision,
  time_end double precision,
  path_length double precision NOT NULL,
  footprint geometry(Polygon, 0) NOT NULL,
  z_min double precision NOT NULL,
  z_max double precision NOT NULL,
  blocks bigint NOT NULL,
  known_voxels bigint NOT NULL,
  occupied_voxels bigint NOT NULL,
  semantic_voxels bigint NOT NULL,
  payload_format integer NOT NULL,
  payload_crc bigint NOT NULL,
  payload_bytes bigint NOT NULL,
  revision integer NOT NULL DEFAULT 1,
  PRIMARY KEY (session, submap));
CREATE INDEX submaps_footprint ON slamvdb.submaps USING gist (footprint);
CREATE TABLE slamvdb.occupancy(
  session bigint NOT NULL,
  submap integer NOT NULL,
  bx integer NOT NULL, by integer NOT NULL, bz integer NOT NULL,
  log_odds bytea NOT NULL,
  crc bigint NOT NULL,
  PRIMARY KEY (session, submap, bx, by, bz),
  FOREIGN KEY (session, submap) REFERENCES slamvdb.submaps ON DELETE CASCADE);
ALTER TABLE slamvdb.occupancy ALTER COLUMN log_odds SET STORAGE EXTERNAL;
CREATE TABLE slamvdb.semantics(
  session bigint NOT NULL,
  submap integer NOT NULL,
  chunk integer NOT NULL,
  keys bytea NOT NULL, counts bytea NOT NULL, embeddings bytea NOT NULL,
  crc bigint NOT NULL,
  stats bytea NOT NULL,
  stats_crc bigint NOT NULL,
  PRIMARY KEY (session, submap, chunk),
  FOREIGN KEY (session, submap) REFERENCES slamvdb.submaps ON DELETE CASCADE);
)sql";

// Version 2: the per-submap summary that lets a region query skip a submap without reading it
// (fleet/fleet_summary.hpp): its embeddings' cap, a unit centroid (real[], the embedding
// dimension) and the largest angle of any embedding from it (radians). NULL, the value of every
// row pushed under version 1, means no summary: such a submap is always read.
constexpr const char* kVersion2 = R"sql(
ALTER TABLE slamvdb.submaps
  ADD COLUMN embedding_centroid real[],
  ADD COLUMN embedding_radius double precision
    CHECK (embedding_radius IS NULL OR (embedding_radius >= 0 AND embedding_centroid IS NOT NULL));
)sql";

// Version 3: the fleet can be split by region across servers (docs/fleet-design.md, "Scale out").
// Every catalog and payload row carries the id of the shard that holds it (0: this database's own
// tables, the only shard of a fleet on one server); a sharded coordinator partitions the three
// tables by that column, each partition a postgres_fdw foreign table on a shard server
// (fleet_shards.cpp). A submap's home tile (a 500 m square of the fleet frame, at the centre of its
// footprint when first pushed) fixes its shard for good; each tile's extent grows with every
// footprint pushed into it, so a region asks only the shards whose tiles' extents meet it.
// Also: embeddings are stored without TOAST compression (STORAGE EXTERNAL, as occupancy's
// log-odds): pglz gains nothing on fp16/fp32 embeddings (the benchmark's rows: 13.1 MB in, 13.1 MB
// stored) and its failed attempt was a quarter of the server's COPY time (docs/fleet-design.md,
// "Measurements"); keys, counts and statistics keep EXTENDED (they compress).
constexpr const char* kVersion3 = R"sql(
ALTER TABLE slamvdb.semantics ALTER COLUMN embeddings SET STORAGE EXTERNAL;
ALTER TABLE slamvdb.submaps ADD COLUMN shard integer NOT NULL DEFAULT 0;
ALTER TABLE slamvdb.occupancy ADD COLUMN shard integer NOT NULL DEFAULT 0;
ALTER TABLE slamvdb.semantics ADD COLUMN shard integer NOT NULL DEFAULT 0;
CREATE TABLE slamvdb.shards(
  id integer PRIMARY KEY CHECK (id > 0),
  name text NOT NULL UNIQUE,
  server name NOT NULL,
  added_at timestamptz NOT NULL DEFAULT now());
CREATE TABLE slamvdb.tiles(
  tile_x integer NOT NULL,
  tile_y integer NOT NULL,
  shard integer NOT NULL,
  x_min double precision NOT NULL DEFAULT 'Infinity',
  y_min double precision NOT NULL DEFAULT 'Infinity',
  x_max double precision NOT NULL DEFAULT '-Infinity',
  y_max double precision NOT NULL DEFAULT '-Infinity',
  PRIMARY KEY (tile_x, tile_y));
CREATE TABLE slamvdb.submap_homes(
  session bigint NOT NULL REFERENCES slamvdb.sessions(id) ON DELETE CASCADE,
  submap integer NOT NULL,
  tile_x integer NOT NULL,
  tile_y integer NOT NULL,
  PRIMARY KEY (session, submap));
INSERT INTO slamvdb.submap_homes
  SELECT session, submap, floor((ST_XMin(footprint) + ST_XMax(footprint)) / 1000)::integer,
         floor((ST_YMin(footprint) + ST_YMax(footprint)) / 1000)::integer FROM slamvdb.submaps;
INSERT INTO slamvdb.tiles
  SELECT h.tile_x, h.tile_y, 0, min(ST_XMin(m.footprint)), min(ST_YMin(m.footprint)), max(ST_XMax(m.footprint)),
         max(ST_YMax(m.footprint))
  FROM slamvdb.submap_homes h JOIN slamvdb.submaps m USING (session, submap) GROUP BY h.tile_x, h.tile_y;
)sql";

constexpr std::array<const char*, kFleetSchemaVersion> kMigrations{kVersion1, kVersion2, kVersion3};

}  // namespace

std::span<const char* const> fleet_migrations() { return kMigrations; }

}  // namespace slamvdb::fleet
