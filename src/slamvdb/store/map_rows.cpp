// Writing and reading the rows of one submap, with every value checked for meaning on the way in.
#include "slamvdb/store/map_rows.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "slamvdb/store/submap_payload.hpp"

namespace slamvdb::store {
namespace {

int64_t submap_crc(const SubmapSummary& s, std::span<const std::byte> pose, int version) {
  Crc crc;
  crc.add(int64_t{s.info.id}).add(pose);
  if (version >= 2) {
    crc.add_real(s.info.time_range.empty() ? 0.0 : s.info.time_range.begin);
    crc.add_real(s.info.time_range.empty() ? 0.0 : s.info.time_range.end);
    crc.add_real(s.info.path_length);
  }
  return crc.add(static_cast<int64_t>(s.blocks))
      .add(static_cast<int64_t>(s.known_voxels))
      .add(static_cast<int64_t>(s.occupied_voxels))
      .add(static_cast<int64_t>(s.semantic_voxels))
      .value();
}

void check_rigid_pose(int id, const Eigen::Matrix4d& m) {
  if (!m.allFinite()) throw Error(fmt::format("submap {} has a non-finite pose", id));
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || std::abs(R.determinant() - 1) > 1e-6 ||
      !m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    throw Error(fmt::format("submap {} has a pose that is not a rigid transform", id));
  if (m.topRightCorner<3, 1>().cwiseAbs().maxCoeff() > 1e9)
    throw Error(fmt::format("submap {} has a pose {:.3g} m away, outside any map", id, m.topRightCorner<3, 1>().norm()));
}

}  // namespace

const char* const kSchema = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE submaps(id INTEGER PRIMARY KEY NOT NULL, pose BLOB NOT NULL, time_begin REAL, time_end REAL,
  path_length REAL NOT NULL, blocks INTEGER NOT NULL, known_voxels INTEGER NOT NULL, occupied_voxels INTEGER NOT NULL,
  semantic_voxels INTEGER NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE occupancy(submap INTEGER NOT NULL, bx INTEGER NOT NULL, by INTEGER NOT NULL, bz INTEGER NOT NULL,
  log_odds BLOB NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE semantics(submap INTEGER NOT NULL, chunk INTEGER NOT NULL, keys BLOB NOT NULL, counts BLOB NOT NULL,
  embeddings BLOB NOT NULL, crc INTEGER NOT NULL, stats BLOB NOT NULL, stats_crc INTEGER NOT NULL, sessions BLOB,
  sessions_crc INTEGER);
CREATE TABLE sessions(id INTEGER PRIMARY KEY NOT NULL, name TEXT NOT NULL, source TEXT NOT NULL, robot TEXT NOT NULL,
  time_begin REAL, time_end REAL, crc INTEGER NOT NULL);
CREATE TABLE submap_sessions(submap INTEGER NOT NULL, session INTEGER NOT NULL, crc INTEGER NOT NULL,
  PRIMARY KEY(submap, session));
)sql";

const char* const kIndexes = R"sql(
CREATE INDEX IF NOT EXISTS occupancy_by_submap ON occupancy(submap);
CREATE INDEX IF NOT EXISTS semantics_by_submap ON semantics(submap, chunk);
)sql";

SubmapSummary summarize(const Submap& s) {
  const VoxelMap& v = s.voxels();
  return {s.info(), v.occupancy().num_blocks(), v.occupancy().num_known_voxels(), v.occupancy().num_occupied_voxels(),
          v.semantics().size()};
}

void write_submap_row(Database& db, const SubmapSummary& s) {
  Statement insert(db,
                   "INSERT INTO submaps(id, pose, time_begin, time_end, path_length, blocks, known_voxels, "
                   "occupied_voxels, semantic_voxels, crc) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  const Eigen::Matrix4d pose = s.info.T_world_submap.matrix();  // column-major
  const auto pose_bytes = std::as_bytes(std::span(pose.data(), 16));
  insert.bind(1, int64_t{s.info.id}).bind(2, pose_bytes);
  if (s.info.time_range.empty()) insert.bind_null(3).bind_null(4);
  else insert.bind_real(3, s.info.time_range.begin).bind_real(4, s.info.time_range.end);
  insert.bind_real(5, s.info.path_length).bind(6, static_cast<int64_t>(s.blocks));
  insert.bind(7, static_cast<int64_t>(s.known_voxels)).bind(8, static_cast<int64_t>(s.occupied_voxels));
  insert.bind(9, static_cast<int64_t>(s.semantic_voxels)).bind(10, submap_crc(s, pose_bytes, 2)).insert();
  write_submap_session_row(db, s.info);
}

std::vector<SubmapSummary> read_submap_rows(Database& db, int version) {
  std::vector<SubmapSummary> submaps;
  Statement rows(db, version >= 2 ? "SELECT id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc, "
                                    "time_begin, time_end, path_length FROM submaps ORDER BY id"
                                  : "SELECT id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc "
                                    "FROM submaps ORDER BY rowid");
  while (rows.step()) {
    const int64_t id = rows.int64(0);
    const auto pose = rows.blob(1);
    SubmapSummary s;
    s.info.id = static_cast<int>(id);
    s.info.finished = true;
    s.blocks = static_cast<std::size_t>(rows.int64(2));
    s.known_voxels = static_cast<std::size_t>(rows.int64(3));
    s.occupied_voxels = static_cast<std::size_t>(rows.int64(4));
    s.semantic_voxels = static_cast<std::size_t>(rows.int64(5));
    if (version >= 2) {
      if (!rows.is_null(7) || !rows.is_null(8)) s.info.time_range = {rows.real(7), rows.real(8)};
      s.info.path_length = rows.real(9);
    }
    if (id != s.info.id || submap_crc(s, pose, version) != rows.int64(6))
      throw Error(fmt::format("CRC mismatch in the row of submap {}: the file is corrupt", id));
    if (pose.size() != 16 * sizeof(double))
      throw Error(fmt::format("submap {} pose has {} bytes, expected 128", id, pose.size()));
    Eigen::Matrix4d m;
    std::memcpy(m.data(), pose.data(), pose.size());
    check_rigid_pose(s.info.id, m);
    s.info.T_world_submap.matrix() = m;
    const TimeRange& t = s.info.time_range;
    if (!std::isfinite(s.info.path_length) || s.info.path_length < 0 ||
        (!t.empty() && !(std::isfinite(t.begin) && std::isfinite(t.end))) ||
        (version >= 2 && rows.is_null(7) != rows.is_null(8)))
      throw Error(fmt::format("submap {} has an impossible time range or path length", id));
    submaps.push_back(s);
  }
  if (version >= 4) read_submap_session_rows(db, submaps);
  return submaps;
}

PayloadBytes write_submap_voxels(Database& db, const Submap& submap, EmbeddingPrecision precision) {
  const int64_t id = submap.id();
  Statement occ(db, "INSERT INTO occupancy(submap, bx, by, bz, log_odds, crc) VALUES(?, ?, ?, ?, ?, ?)");
  Statement sem(db,
                "INSERT INTO semantics(submap, chunk, keys, counts, embeddings, crc, stats, stats_crc, sessions, "
                "sessions_crc) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  return encode_submap_payload(
      submap, precision,
      [&](const OccupancyRow& r) {
        occ.bind(1, id).bind(2, r.key.x()).bind(3, r.key.y()).bind(4, r.key.z()).bind(5, r.log_odds).bind(6, r.crc).insert();
      },
      [&](const SemanticChunkRow& r) {
        sem.bind(1, id).bind(2, r.chunk).bind(3, r.keys).bind(4, r.counts).bind(5, r.embeddings);
        sem.bind(6, r.crc).bind(7, r.stats).bind(8, r.stats_crc);
        if (r.sessions.empty()) sem.bind_null(9).bind_null(10);
        else sem.bind(9, r.sessions).bind(10, r.sessions_crc);
        sem.insert();
      });
}

OccupancyGrid read_submap_occupancy(Database& db, int version, const SubmapSummary& summary, const MapParams& params) {
  const int64_t id = summary.info.id;
  OccupancyRowReader reader(id, version, params);
  Statement occ(db, "SELECT bx, by, bz, log_odds, crc FROM occupancy WHERE submap = ?");
  occ.bind(1, id);
  while (occ.step()) reader.add(occ.int64(0), occ.int64(1), occ.int64(2), occ.blob(3), occ.int64(4));
  return reader.finish(summary);
}

SemanticLayer read_submap_semantics(Database& db, int version, const SubmapSummary& summary, const MapParams& params) {
  const int64_t id = summary.info.id;
  SemanticChunkReader reader(id, version, params);
  Statement sem(db, version >= 5   ? "SELECT keys, counts, embeddings, crc, chunk, stats, stats_crc, sessions, "
                                     "sessions_crc FROM semantics WHERE submap = ? ORDER BY chunk"
                    : version >= 3 ? "SELECT keys, counts, embeddings, crc, chunk, stats, stats_crc FROM semantics "
                                     "WHERE submap = ? ORDER BY chunk"
                    : version >= 2 ? "SELECT keys, counts, embeddings, crc, chunk FROM semantics WHERE submap = ? ORDER BY chunk"
                                   : "SELECT keys, counts, embeddings, crc FROM semantics WHERE submap = ? ORDER BY rowid");
  sem.bind(1, id);
  while (sem.step()) {
    const std::optional<int64_t> chunk = version >= 2 ? std::optional(sem.int64(4)) : std::nullopt;
    if (version >= 5)
      reader.add(chunk, sem.blob(0), sem.blob(1), sem.blob(2), sem.int64(3), sem.blob(5), sem.int64(6),
                 sem.is_null(7) ? std::nullopt : std::optional(sem.blob(7)),
                 sem.is_null(8) ? std::nullopt : std::optional(sem.int64(8)));
    else if (version >= 3) reader.add(chunk, sem.blob(0), sem.blob(1), sem.blob(2), sem.int64(3), sem.blob(5), sem.int64(6));
    else reader.add(chunk, sem.blob(0), sem.blob(1), sem.blob(2), sem.int64(3), {}, 0);
  }
  return reader.finish(summary);
}

void check_entry_sessions(const SemanticLayer& layer, int submap, const std::vector<SessionInfo>& sessions) {
  std::optional<uint16_t> unknown;
  layer.for_each([&](SemanticLayer::Handle h) {
    const uint16_t s = layer.stored_session_of(h);
    if (unknown || s == SemanticLayer::kOwnSession) return;
    if (std::none_of(sessions.begin(), sessions.end(), [&](const SessionInfo& i) { return i.id == s; })) unknown = s;
  });
  if (unknown)
    throw Error(fmt::format("a semantic voxel of submap {} was last observed in session {}, which the file does not list",
                            submap, *unknown));
}

void check_no_orphan_rows(Database& db) {
  for (const char* table : {"occupancy", "semantics"}) {
    Statement orphans(db, fmt::format("SELECT DISTINCT submap FROM {} WHERE submap NOT IN (SELECT id FROM submaps) LIMIT 1",
                                      table));
    if (orphans.step())
      throw Error(fmt::format("a row of table {} refers to submap {}, which is not in the file", table, orphans.int64(0)));
  }
}

}  // namespace slamvdb::store
