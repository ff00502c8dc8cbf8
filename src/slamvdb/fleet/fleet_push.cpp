// Pushing a map's submaps into the fleet: the fleet's shared parameters checked first, the session
// row, then one transaction per submap (catalog row + payload rows, or the catalog row alone when
// only the anchor moved).
#include <fmt/format.h>

#include <array>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <pqxx/stream_to>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"
#include "slamvdb/fleet/fleet_push_rows.hpp"
#include "slamvdb/fleet/fleet_rows.hpp"
#include "slamvdb/fleet/fleet_summary.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/store/map_rows.hpp"
#include "slamvdb/store/submap_payload.hpp"

namespace slamvdb::fleet {
namespace {

// The map file meta entries every map of one fleet shares: how payload rows are read (voxel size,
// embedding dimension and precision, clamping) and what they mean (embedding space, ontology).
// Sensor settings (hit/miss log-odds, ranges) may differ between robots.
constexpr std::array<const char*, 9> kSharedEntries{"voxel_size",  "semantic_dim",       "semantic_precision",
                                                    "model_id",    "ontology",           "clamp_min",
                                                    "clamp_max",   "occupied_threshold", "semantic_single_view"};

std::string entry_or_absent(const store::Meta& meta, const char* key) {
  const auto it = meta.find(key);
  return it == meta.end() ? std::string("(absent)") : it->second;
}

// The fleet row's parameters: the defining map's meta entries without those that describe one
// map only (its source, options, colours, fusion rule); pull makes maps from them.
nlohmann::json fleet_entries(const MapParams& params, const MapInfo& info) {
  store::Meta meta = store::map_meta(params, info);
  for (const char* own : {"source", "config", "colour_basis", "fusion", "features"}) meta.erase(own);
  nlohmann::json entries = nlohmann::json::object();
  for (const auto& [key, value] : meta) entries[key] = value;
  for (const char* key : kSharedEntries) entries[key] = entry_or_absent(meta, key);
  return entries;
}

}  // namespace

// Checks the map against the fleet row; with `define`, the first map pushed defines it.
void check_fleet(pqxx::transaction_base& tx, const MapParams& params, const MapInfo& info, bool define,
                 const std::string& display_url) {
  const nlohmann::json ours = fleet_entries(params, info);
  if (define)
    tx.exec_params(
        "INSERT INTO slamvdb.fleet(voxel_size, semantic_dim, model_id, ontology, params) "
        "VALUES ($1, $2, $3, $4, $5::jsonb) ON CONFLICT (single) DO NOTHING",
        params.occupancy.voxel_size, params.semantic.dim, info.model_id, info.ontology, ours.dump());
  const pqxx::result fleet = tx.exec("SELECT params::text FROM slamvdb.fleet");
  if (fleet.empty()) return;  // no map pushed yet: any map may define the fleet
  const std::map<std::string, std::string> theirs = parse_fleet_entries(fleet[0][0].c_str(), display_url);
  for (const char* key : kSharedEntries) {
    const auto it = theirs.find(key);
    const std::string a = it != theirs.end() ? it->second : "(absent)";
    const std::string b = ours[key].get<std::string>();
    if (a != b)
      throw Error(fmt::format("the map differs from the fleet at {} in '{}': the fleet has '{}', the map '{}'; "
                              "nothing was pushed (one fleet holds one embedding space, voxel size and ontology)",
                              display_url, key, a, b));
  }
}


void FleetDatabase::check_map(const MapParams& params, const MapInfo& info) {
  ensure_schema();
  try {
    pqxx::read_transaction tx(connection_->connection);
    check_fleet(tx, params, info, false, display_url_);
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
}

namespace {

struct OwnedOccupancyRow {
  BlockKey key;
  std::vector<std::byte> log_odds;
  int64_t crc;
};
struct OwnedSemanticRow {
  int64_t chunk;
  std::vector<std::byte> keys, counts, embeddings, stats;
  int64_t crc, stats_crc;
};
std::vector<std::byte> owned(std::span<const std::byte> bytes) { return {bytes.begin(), bytes.end()}; }

// A bytea value in PostgreSQL's hex input form (\x...), for COPY's text format: libpqxx 6's
// stream_to writes text, and hex is the one bytea text form without escaping rules.
std::string bytea_hex(const std::vector<std::byte>& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out = "\\x";
  out.reserve(2 + 2 * bytes.size());
  for (const std::byte b : bytes) {
    const auto v = static_cast<unsigned>(b);
    out += kDigits[v >> 4];
    out += kDigits[v & 15u];
  }
  return out;
}

// One submap's rows, encoded once, and what identifies its payload.
struct EncodedSubmap {
  std::vector<OwnedOccupancyRow> occupancy;
  std::vector<OwnedSemanticRow> semantics;
  store::PayloadBytes bytes;
  int64_t payload_crc = 0;  // over the rows' CRCs and the submap's own values
  Eigen::AlignedBox3d bounds_local, bounds_fleet;  // of its blocks, in its own frame and in the fleet's
  std::optional<EmbeddingCap> cap;  // the summary a query prunes by (none: no usable embedding)
  std::string centroid_array() const {  // as a real[] literal (9 digits: a float exactly)
    std::string out = "{";
    if (cap)
      for (const float c : cap->centroid) out += fmt::format("{}{:.9g}", out.size() > 1 ? "," : "", c);
    return out + "}";
  }
};

}  // namespace

// A submap's footprint box in the fleet frame from the box of its blocks in its own frame (a rotated
// box is held by the box of its corners); an empty submap's is its anchor.
Eigen::AlignedBox3d fleet_box(const Eigen::AlignedBox3d& local, const Pose& T_fleet_submap) {
  Eigen::AlignedBox3d out;
  if (local.isEmpty()) return out.extend(T_fleet_submap.translation());
  for (int corner = 0; corner < 8; ++corner)
    out.extend(T_fleet_submap * local.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)));
  return out;
}

namespace {

EncodedSubmap encode(const Submap& submap, const MapParams& params, const Pose& T_fleet_session) {
  EncodedSubmap out;
  store::Crc crc;
  const SubmapInfo& info = submap.info();
  crc.add(int64_t{info.id}).add_real(info.path_length);
  if (!info.time_range.empty()) crc.add_real(info.time_range.begin).add_real(info.time_range.end);
  out.bytes = store::encode_submap_payload(
      submap, params.semantic.precision,
      [&](const store::OccupancyRow& r) {
        out.occupancy.push_back({r.key, owned(r.log_odds), r.crc});
        crc.add(r.crc);
      },
      [&](const store::SemanticChunkRow& r) {
        out.semantics.push_back({r.chunk, owned(r.keys), owned(r.counts), owned(r.embeddings), owned(r.stats), r.crc,
                                 r.stats_crc});
        crc.add(r.crc).add(r.stats_crc);
      });
  out.payload_crc = crc.value();
  out.cap = embedding_cap(submap.voxels().semantics());
  // The footprint: the box of every block's corners (blocks, not voxels, bound it: cheaper and still
  // a superset), moved to the fleet frame.
  const double block = kBlockSide * params.occupancy.voxel_size;
  for (const auto& [bk, unused] : submap.voxels().occupancy().blocks()) {
    out.bounds_local.extend(bk.cast<double>() * block);
    out.bounds_local.extend((bk.cast<double>() + Vec3d::Ones()) * block);
  }
  out.bounds_fleet = fleet_box(out.bounds_local, T_fleet_session * info.T_world_submap);
  return out;
}

// The payload rows by COPY: 36x faster than one INSERT per row here (4 000 rows of 150 bytes over
// a Unix socket: 26 ms against 0.94 s).
void copy_payload(pqxx::work& tx, int64_t session, int submap, int shard, const EncodedSubmap& e) {
  pqxx::stream_to occupancy(tx, "slamvdb.occupancy",
                            std::vector<std::string>{"session", "submap", "bx", "by", "bz", "log_odds", "crc", "shard"});
  for (const OwnedOccupancyRow& r : e.occupancy)
    occupancy << std::make_tuple(session, submap, r.key.x(), r.key.y(), r.key.z(), bytea_hex(r.log_odds), r.crc, shard);
  occupancy.complete();
  pqxx::stream_to semantics(tx, "slamvdb.semantics",
                            std::vector<std::string>{"session", "submap", "chunk", "keys", "counts", "embeddings", "crc",
                                                     "stats", "stats_crc", "shard"});
  for (const OwnedSemanticRow& r : e.semantics)
    semantics << std::make_tuple(session, submap, r.chunk, bytea_hex(r.keys), bytea_hex(r.counts),
                                 bytea_hex(r.embeddings), r.crc, bytea_hex(r.stats), r.stats_crc, shard);
  semantics.complete();
}

// A catalog row rewritten: the values in statement order after (session, submap) = ($1, $2).
const std::string kUpdateCatalog =
    "UPDATE slamvdb.submaps SET t_world_submap = $3::float8[], time_begin = CASE WHEN $4 THEN $5::float8 END, "
    "time_end = CASE WHEN $4 THEN $6::float8 END, path_length = $7, "
    "footprint = ST_MakeEnvelope($8, $9, $10, $11, 0), z_min = $12, z_max = $13, blocks = $14, known_voxels = $15, "
    "occupied_voxels = $16, semantic_voxels = $17, payload_format = $18, payload_crc = $19, payload_bytes = $20, "
    "embedding_centroid = CASE WHEN $21 THEN $22::real[] END, embedding_radius = CASE WHEN $21 THEN $23::float8 END, "
    "revision = revision + 1 WHERE session = $1 AND submap = $2 AND shard = $24";

}  // namespace

// The shard that holds a submap: its home tile (the tile of its footprint's centre at its first
// push, kept for good, so a correction never moves rows between servers) and that tile's shard (a
// new tile goes to the newest shard). The homes row is locked until the submap's transaction ends:
// two pushers of one submap are serialised here. The tile's extent grows to hold the footprint, so
// a region query finds every shard that holds a submap meeting it (fleet_connection.hpp).
int submap_shard(pqxx::work& tx, int64_t session, int submap, const Eigen::AlignedBox3d& b) {
  const auto tile = [](double lo, double hi) { return static_cast<int>(std::floor(0.5 * (lo + hi) / kFleetTileSide)); };
  const pqxx::row home = tx.exec_params1(
      "INSERT INTO slamvdb.submap_homes AS h(session, submap, tile_x, tile_y) VALUES ($1, $2, $3, $4) "
      "ON CONFLICT (session, submap) DO UPDATE SET tile_x = h.tile_x RETURNING tile_x, tile_y",
      session, submap, tile(b.min().x(), b.max().x()), tile(b.min().y(), b.max().y()));
  const int tile_x = home[0].as<int>(), tile_y = home[1].as<int>();
  const pqxx::result known = tx.exec_params(
      "SELECT shard, x_min <= $3 AND y_min <= $4 AND x_max >= $5 AND y_max >= $6 FROM slamvdb.tiles "
      "WHERE tile_x = $1 AND tile_y = $2",
      tile_x, tile_y, b.min().x(), b.min().y(), b.max().x(), b.max().y());
  if (!known.empty() && known[0][1].as<bool>()) return known[0][0].as<int>();  // no write: no lock on the tile
  return tx
      .exec_params1(
          "INSERT INTO slamvdb.tiles AS t(tile_x, tile_y, shard, x_min, y_min, x_max, y_max) "
          "VALUES ($1, $2, coalesce((SELECT max(id) FROM slamvdb.shards), 0), $3, $4, $5, $6) "
          "ON CONFLICT (tile_x, tile_y) DO UPDATE SET x_min = least(t.x_min, $3), y_min = least(t.y_min, $4), "
          "x_max = greatest(t.x_max, $5), y_max = greatest(t.y_max, $6) RETURNING shard",
          tile_x, tile_y, b.min().x(), b.min().y(), b.max().x(), b.max().y())[0]
      .as<int>();
}

// One submap's catalog row and payload rows in `tx` (FleetPushSession::push): inserted when new,
// the catalog row alone when only its anchor moved, nothing when unchanged, all replaced when its
// payload changed. Returns its blocks' box in its own frame.
Eigen::AlignedBox3d write_submap(pqxx::work& tx, int64_t session, const Submap& submap, const MapParams& params,
                                 const Pose& T_fleet_session, PushReport& report) {
  const SubmapInfo& info = submap.info();
  const EncodedSubmap e = encode(submap, params, T_fleet_session);
  const Eigen::AlignedBox3d& b = e.bounds_fleet;
  const VoxelMap& v = submap.voxels();
  const bool timed = !info.time_range.empty();
  const auto total_bytes = static_cast<int64_t>(e.bytes.occupancy + e.bytes.semantics);
  const int shard = submap_shard(tx, session, info.id, b);
  const auto values = [&](const std::string& sql) {
    return tx.exec_params(sql, session, info.id, pose_array(info.T_world_submap), timed,
                          timed ? info.time_range.begin : 0.0, timed ? info.time_range.end : 0.0, info.path_length,
                          b.min().x(), b.min().y(), b.max().x(), b.max().y(), b.min().z(), b.max().z(),
                          static_cast<int64_t>(v.occupancy().num_blocks()),
                          static_cast<int64_t>(v.occupancy().num_known_voxels()),
                          static_cast<int64_t>(v.occupancy().num_occupied_voxels()),
                          static_cast<int64_t>(v.semantics().size()), kMapFormatVersion, e.payload_crc, total_bytes,
                          e.cap.has_value(), e.centroid_array(), e.cap ? e.cap->radius : 0.0, shard);
  };
  // The row as it is, locked: a second pusher of the same submap waits here.
  const pqxx::result existing = tx.exec_params(
      "SELECT payload_crc = $3 AND payload_format = $4, t_world_submap = $5::float8[] AND "
      "footprint = ST_MakeEnvelope($6, $7, $8, $9, 0) AND z_min = $10 AND z_max = $11 "
      "AND (embedding_radius IS NOT NULL OR NOT $12) "
      "FROM slamvdb.submaps WHERE session = $1 AND submap = $2 AND shard = $13 FOR UPDATE",
      session, info.id, e.payload_crc, kMapFormatVersion, pose_array(info.T_world_submap), b.min().x(), b.min().y(),
      b.max().x(), b.max().y(), b.min().z(), b.max().z(), e.cap.has_value(), shard);
  bool write_payload = true;
  if (existing.empty()) {
    values("INSERT INTO slamvdb.submaps(session, submap, t_world_submap, time_begin, time_end, path_length, "
           "footprint, z_min, z_max, blocks, known_voxels, occupied_voxels, semantic_voxels, payload_format, "
           "payload_crc, payload_bytes, embedding_centroid, embedding_radius, shard) VALUES ($1, $2, $3::float8[], "
           "CASE WHEN $4 THEN $5::float8 END, CASE WHEN $4 THEN $6::float8 END, $7, "
           "ST_MakeEnvelope($8, $9, $10, $11, 0), $12, $13, $14, $15, $16, $17, $18, $19, $20, "
           "CASE WHEN $21 THEN $22::real[] END, CASE WHEN $21 THEN $23::float8 END, $24)");
    ++report.submaps_added;
  } else if (existing[0][0].as<bool>()) {
    write_payload = false;
    if (existing[0][1].as<bool>()) {
      ++report.submaps_unchanged;
    } else {
      values(kUpdateCatalog);
      ++report.anchors_moved;
    }
  } else {
    for (const char* table : {"occupancy", "semantics"})
      tx.exec_params(fmt::format("DELETE FROM slamvdb.{} WHERE session = $1 AND submap = $2 AND shard = $3", table),
                     session, info.id, shard);
    values(kUpdateCatalog);
    ++report.payloads_replaced;
  }
  if (write_payload) {
    copy_payload(tx, session, info.id, shard, e);
    report.rows_written += e.occupancy.size() + e.semantics.size();
    report.payload_bytes += static_cast<uint64_t>(total_bytes);
  }
  // The session's time range grows with its submaps (LEAST and GREATEST skip a new session's NULL).
  if (timed)
    tx.exec_params("UPDATE slamvdb.sessions SET time_begin = LEAST(time_begin, $2), time_end = GREATEST(time_end, $3) "
                   "WHERE id = $1 AND (time_begin IS NULL OR time_begin > $2 OR time_end < $3)",
                   session, info.time_range.begin, info.time_range.end);
  return e.bounds_local;
}

// The shard that holds a pushed submap (its home tile's); none when it was never pushed.
std::optional<int> pushed_shard(pqxx::work& tx, int64_t session, int submap) {
  const pqxx::result r = tx.exec_params(
      "SELECT t.shard FROM slamvdb.submap_homes h JOIN slamvdb.tiles t USING (tile_x, tile_y) "
      "WHERE h.session = $1 AND h.submap = $2",
      session, submap);
  if (r.empty()) return std::nullopt;
  return r[0][0].as<int>();
}

}  // namespace slamvdb::fleet
