// Each voxel's last-observed session in the map file (format version 5: the `sessions` and
// `sessions_crc` columns of table semantics): written and read back, NULL for a chunk whose
// voxels are all the submap's own, older files read as "all own", damage refused by name.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "slamvdb/store/sqlite_db.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using namespace slamvdb::testing;

// make_map's submaps (3 and -7) in session 0 ("monday"); every third semantic voxel of submap 3
// last observed by session `tag` (1, "friday", unless told otherwise).
SemanticMap last_session_map(int tag = 1) {
  SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 16, 9, [&](int id, VoxelMap& voxels) {
    if (id != 3) return;
    SemanticLayer& layer = voxels.semantics();
    int n = 0;
    layer.for_each([&](SemanticLayer::Handle h) {
      if (n++ % 3 == 0) layer.set_session(h, tag);
    });
  });
  MapInfo info = map.info();
  info.sessions = {{0, "monday", "SIMULATED drive A", "", {}}, {1, "friday", "SIMULATED drive B", "", {}}};
  map.set_info(info);
  return map;
}

// Every semantic voxel's last-observed session, by submap and key.
std::map<std::pair<int, VoxelKey>, int> last_sessions_of(const SemanticMap& map) {
  std::map<std::pair<int, VoxelKey>, int> out;
  for (const SubmapInfo& s : map.submaps())
    map.read_submap(s.id, [&](const Submap& submap) {
      const SemanticLayer& layer = submap.voxels().semantics();
      layer.for_each([&](SemanticLayer::Handle h) { out[{s.id, layer.key_of(h)}] = layer.session_of(h); });
    });
  return out;
}

void exec_sql_on(const fs::path& file, const std::string& sql) {
  store::Database db(file, SQLITE_OPEN_READWRITE);
  db.exec(sql);
}

TEST_F(MapStoreTest, LastObservedSessionsRoundTrip) {
  const SemanticMap map = last_session_map();
  const auto expected = last_sessions_of(map);
  std::size_t by_friday = 0;
  for (const auto& [key, session] : expected) by_friday += session == 1;
  ASSERT_GT(by_friday, 100u);
  const fs::path path = dir_ / "site.svdb";
  save_map(path, map);
  EXPECT_EQ(read_map_summary(path).format_version, kMapFormatVersion);
  EXPECT_EQ(last_sessions_of(load_map(path)), expected);
  // Only submap 3's chunks carry the column: a submap whose voxels are all its own pays nothing.
  store::Database db(path, SQLITE_OPEN_READONLY);
  store::Statement rows(db, "SELECT submap, sessions IS NULL, sessions_crc IS NULL FROM semantics");
  while (rows.step()) {
    EXPECT_EQ(rows.int64(1), rows.int64(0) == 3 ? 0 : 1) << "submap " << rows.int64(0);
    EXPECT_EQ(rows.int64(2), rows.int64(1));
  }
}

TEST_F(MapStoreTest, AVersion4FileLoadsWithEveryVoxelInItsSubmapsSession) {
  const fs::path path = dir_ / "v4.svdb";
  save_map(path, last_session_map());
  const std::string v = "4";
  const int64_t crc = store::Crc().add("format_version", sizeof "format_version").add(v.data(), v.size()).value();
  exec_sql_on(path, "ALTER TABLE semantics DROP COLUMN sessions; ALTER TABLE semantics DROP COLUMN sessions_crc; "
                    "PRAGMA user_version = 4; UPDATE meta SET value = '4', crc = " +
                        std::to_string(crc) + " WHERE key = 'format_version';");
  EXPECT_EQ(read_map_summary(path).format_version, 4);
  for (const auto& [key, session] : last_sessions_of(load_map(path))) EXPECT_EQ(session, 0);
}

TEST_F(MapStoreTest, DamagedLastObservedSessionsAreRefusedByName) {
  const fs::path good = dir_ / "good.svdb";
  save_map(good, last_session_map());
  const auto refusal = [&](const std::string& sql) {
    const fs::path bad = dir_ / "bad.svdb";
    fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
    exec_sql_on(bad, sql);
    try {
      load_map(bad);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("loaded");
  };
  EXPECT_NE(refusal("UPDATE semantics SET sessions = substr(sessions, 3) || x'0100' WHERE submap = 3")
                .find("CRC mismatch in the last-observed sessions of semantic chunk 0 of submap 3"),
            std::string::npos);
  EXPECT_NE(refusal("UPDATE semantics SET sessions_crc = NULL WHERE submap = 3")
                .find("semantic chunk 0 of submap 3 has last-observed sessions without their CRC"),
            std::string::npos);
  EXPECT_NE(refusal("UPDATE semantics SET sessions = x'0100' WHERE submap = -7").find("submap -7"), std::string::npos);
  // A session the file does not list (written by a map that tagged one).
  const fs::path unknown = dir_ / "unknown.svdb";
  save_map(unknown, last_session_map(9));
  try {
    load_map(unknown);
    FAIL() << "a voxel of an unlisted session was loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a semantic voxel of submap 3 was last observed in session 9, which the file "
                                         "does not list"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace slamvdb
