// Sessions in the map file (format version 4): written and read back, old files read as one
// session named after the file, damaged session rows refused with their name.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <string>

#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/store/sqlite_db.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using namespace slamvdb::testing;

// make_map's two submaps (ids 3 and -7, time 10..14.5 and 20..24.5) in two sessions, ids 5 and 2.
SemanticMap two_session_map() {
  SemanticMap source = make_map(EmbeddingPrecision::kFloat16, 16, 4);
  MapInfo info = source.info();
  info.sessions = {{5, "monday", "SIMULATED drive A", "husky-1", {}}, {2, "friday", "SIMULATED drive B", "", {}}};
  SemanticMap map(source.params(), info);
  for (const SubmapInfo& s : source.submaps()) {
    auto [info_of_submap, voxels] = source.remove_finished_submap(s.id);
    info_of_submap.session = s.id == 3 ? 5 : 2;
    map.add_finished_submap(info_of_submap, std::move(voxels));
  }
  return map;
}

void expect_two_sessions(const std::vector<SessionInfo>& sessions) {
  ASSERT_EQ(sessions.size(), 2u);  // by id
  EXPECT_EQ(sessions[0].id, 2);
  EXPECT_EQ(sessions[0].name, "friday");
  EXPECT_EQ(sessions[0].source, "SIMULATED drive B");
  EXPECT_EQ(sessions[0].robot, "");
  EXPECT_EQ(sessions[0].time.begin, 20.0);  // from its submap, whatever the info said
  EXPECT_EQ(sessions[0].time.end, 24.5);
  EXPECT_EQ(sessions[1].id, 5);
  EXPECT_EQ(sessions[1].name, "monday");
  EXPECT_EQ(sessions[1].robot, "husky-1");
  EXPECT_EQ(sessions[1].time.begin, 10.0);
  EXPECT_EQ(sessions[1].time.end, 14.5);
}

void exec_sql(const fs::path& file, const std::string& sql) {
  store::Database db(file, SQLITE_OPEN_READWRITE);
  db.exec(sql);
}

TEST_F(MapStoreTest, SessionsRoundTrip) {
  const fs::path path = dir_ / "site.svdb";
  save_map(path, two_session_map());
  const MapFileSummary s = read_map_summary(path);
  EXPECT_EQ(s.format_version, kMapFormatVersion);
  expect_two_sessions(s.info.sessions);
  ASSERT_EQ(s.submaps.size(), 2u);
  EXPECT_EQ(s.submaps[0].info.id, -7);
  EXPECT_EQ(s.submaps[0].info.session, 2);
  EXPECT_EQ(s.submaps[1].info.session, 5);
  const SemanticMap loaded = load_map(path);
  expect_two_sessions(loaded.info().sessions);
  EXPECT_EQ(loaded.submap_info(3)->session, 5);
  EXPECT_EQ(loaded.submap_info(-7)->session, 2);
  // Saved again under another name, the sessions keep their names (the file's name is only the
  // name of a map's implicit session).
  save_map(dir_ / "copy.svdb", loaded);
  expect_two_sessions(read_map_summary(dir_ / "copy.svdb").info.sessions);
}

TEST_F(MapStoreTest, AMapWithoutSessionsIsOneSessionNamedAfterItsFile) {
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 16, 5);
  const fs::path path = dir_ / "drive_a.svdb";
  save_map(path, map);
  const MapFileSummary s = read_map_summary(path);
  ASSERT_EQ(s.info.sessions.size(), 1u);
  EXPECT_EQ(s.info.sessions[0].id, 0);
  EXPECT_EQ(s.info.sessions[0].name, "drive_a");
  EXPECT_EQ(s.info.sessions[0].source, map.info().source);
  EXPECT_EQ(s.info.sessions[0].time.begin, 10.0);
  EXPECT_EQ(s.info.sessions[0].time.end, 24.5);
}

TEST_F(MapStoreTest, AVersion3FileLoadsAsOneSessionNamedAfterTheFile) {
  // A version 3 file: the current file without the two session tables, user_version 3 (its
  // other tables and CRCs are version 3's, which version 4 left unchanged).
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 16, 6);
  const fs::path path = dir_ / "tuesday.svdb";
  save_map(path, map);
  const std::string v = "3";
  const int64_t crc = store::Crc().add("format_version", sizeof "format_version").add(v.data(), v.size()).value();
  exec_sql(path, "DROP TABLE sessions; DROP TABLE submap_sessions; PRAGMA user_version = 3; UPDATE meta SET value = '3', "
                 "crc = " + std::to_string(crc) + " WHERE key = 'format_version';");
  const MapFileSummary s = read_map_summary(path);
  EXPECT_EQ(s.format_version, 3);
  ASSERT_EQ(s.info.sessions.size(), 1u);
  EXPECT_EQ(s.info.sessions[0].name, "tuesday");
  EXPECT_EQ(s.info.sessions[0].source, map.info().source);
  EXPECT_EQ(s.info.sessions[0].time.begin, 10.0);  // the union of its submaps' time ranges
  EXPECT_EQ(s.info.sessions[0].time.end, 24.5);
  const SemanticMap loaded = load_map(path);
  expect_identical(map, loaded);
  for (const SubmapInfo& info : loaded.submaps()) EXPECT_EQ(info.session, 0);
  // Saved again, it is a current file that keeps the name.
  save_map(dir_ / "upgraded.svdb", loaded);
  const MapFileSummary upgraded = read_map_summary(dir_ / "upgraded.svdb");
  EXPECT_EQ(upgraded.format_version, kMapFormatVersion);
  ASSERT_EQ(upgraded.info.sessions.size(), 1u);
  EXPECT_EQ(upgraded.info.sessions[0].name, "tuesday");
}

TEST_F(MapStoreTest, ANewerFormatIsRefusedNamingBothVersions) {
  const fs::path path = dir_ / "future.svdb";
  save_map(path, make_map(EmbeddingPrecision::kFloat16, 16, 7));
  exec_sql(path, fmt::format("PRAGMA user_version = {};", kMapFormatVersion + 1));
  try {
    read_map_summary(path);
    FAIL() << "a newer format was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("map format version {} is newer than this slamvdb supports ({})",
                                                      kMapFormatVersion + 1, kMapFormatVersion)),
              std::string::npos) << e.what();
  }
}

TEST_F(MapStoreTest, DamagedSessionRowsAreRefusedByName) {
  const fs::path good = dir_ / "good.svdb";
  save_map(good, two_session_map());
  const auto refusal = [&](const std::string& sql) {
    const fs::path bad = dir_ / "bad.svdb";
    fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
    exec_sql(bad, sql);
    try {
      load_map(bad);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("loaded");
  };
  EXPECT_NE(refusal("UPDATE sessions SET name = 'mondax' WHERE id = 5").find("CRC mismatch in the row of session 5"),
            std::string::npos);
  EXPECT_NE(refusal("UPDATE sessions SET time_end = NULL WHERE id = 2").find("session 2 has half a time range"),
            std::string::npos);
  EXPECT_NE(refusal("DELETE FROM sessions WHERE id = 2").find("submap -7 belongs to session 2, which is not in table sessions"),
            std::string::npos);
  EXPECT_NE(refusal("DELETE FROM submap_sessions WHERE submap = 3").find("submap 3 has no session"), std::string::npos);
  EXPECT_NE(refusal("UPDATE submap_sessions SET session = 5 WHERE submap = -7").find("CRC mismatch in the session row of submap -7"),
            std::string::npos);
}

TEST_F(MapStoreTest, AGrowingMapFileRecordsItsSession) {
  // The streaming writer (map, slam): the session row is there from the start, its time range
  // set when the map is finished.
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 16, 8);
  const fs::path path = dir_ / "streamed.svdb";
  auto writer = MapFileWriter::create(path, map.params(), map.info());
  ASSERT_EQ(read_map_summary(path).info.sessions.size(), 1u);
  EXPECT_TRUE(read_map_summary(path).info.sessions[0].time.empty());
  for (const SubmapInfo& s : map.submaps()) writer->save_finished(map, s.id);
  writer->finish(map.info(), 0);
  const MapFileSummary s = read_map_summary(path);
  ASSERT_EQ(s.info.sessions.size(), 1u);
  EXPECT_EQ(s.info.sessions[0].name, "streamed");
  EXPECT_EQ(s.info.sessions[0].time.begin, 10.0);
  EXPECT_EQ(s.info.sessions[0].time.end, 24.5);
}

}  // namespace
}  // namespace slamvdb
