#include "slamvdb/store/map_store.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <ctime>
#include <thread>

#include "slamvdb/core/half.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using namespace slamvdb::testing;

TEST_F(MapStoreTest, RoundTripIsBitExactFp16AndFp32) {
  for (const auto precision : {EmbeddingPrecision::kFloat16, EmbeddingPrecision::kFloat32}) {
    const SemanticMap map = make_map(precision, 64, 1);
    const fs::path path = dir_ / "map.svdb";
    save_map(path, map);
    EXPECT_EQ(files_in(dir_), std::vector<fs::path>{"map.svdb"});  // no temp file left behind
    const SemanticMap loaded = load_map(path);
    expect_identical(map, loaded);
    EXPECT_EQ(loaded.num_known_voxels(), map.num_known_voxels());
    EXPECT_EQ(loaded.num_semantic_voxels(), map.num_semantic_voxels());
    // Same map, same bytes: rows are written in key order, not hash order.
    save_map(dir_ / "again.svdb", loaded);
    EXPECT_EQ(read_bytes(path), read_bytes(dir_ / "again.svdb"));
    fs::remove(dir_ / "again.svdb");
  }
}

TEST_F(MapStoreTest, SummaryReadsMetadataAndCounts) {
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 32, 2);
  const fs::path path = dir_ / "map.svdb";
  save_map(path, map);
  const MapFileSummary s = read_map_summary(path);
  EXPECT_EQ(s.format_version, kMapFormatVersion);
  expect_same_params(s.params, map.params());
  EXPECT_EQ(s.info.source, map.info().source);
  EXPECT_EQ(s.known_voxels, map.num_known_voxels());
  EXPECT_EQ(s.occupied_voxels, map.num_occupied_voxels());
  EXPECT_EQ(s.semantic_voxels, map.num_semantic_voxels());
  EXPECT_EQ(s.memory_bytes, map.memory_bytes());
  EXPECT_EQ(s.file_bytes, fs::file_size(path));
  EXPECT_EQ(s.semantic_payload_bytes, map.num_semantic_voxels() * (12 + 4 + 32 * 2 + 8));  // + statistics (format 3)
  ASSERT_EQ(s.submaps.size(), 2u);
  const SubmapSummary& first = s.submaps[0];  // in id order
  EXPECT_EQ(first.info.id, -7);
  EXPECT_EQ(first.info.T_world_submap.matrix(), map.submap_info(-7)->T_world_submap.matrix());
  EXPECT_EQ(first.info.time_range.begin, 20.0);
  EXPECT_EQ(first.info.time_range.end, 24.5);
  EXPECT_EQ(first.info.path_length, 12.5);
  map.read_submap(-7, [&](const Submap& sm) {
    EXPECT_EQ(first.blocks, sm.voxels().occupancy().num_blocks());
    EXPECT_EQ(first.semantic_voxels, sm.voxels().semantics().size());
  });
}

TEST_F(MapStoreTest, EmptyMapRoundTrips) {
  MapParams params;
  params.semantic = {8, EmbeddingPrecision::kFloat32};
  const SemanticMap map(params);
  save_map(dir_ / "empty.svdb", map);
  const SemanticMap loaded = load_map(dir_ / "empty.svdb");
  expect_identical(map, loaded);
}

TEST_F(MapStoreTest, SavedFilesGetNormalPermissionsOrKeepTheReplacedOnes) {
  const mode_t mask = umask(0);
  umask(mask);
  const fs::path path = dir_ / "map.svdb";
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 8, 8);
  save_map(path, map);
  EXPECT_EQ(static_cast<mode_t>(fs::status(path).permissions()), 0666 & ~mask);
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  save_map(path, map);
  EXPECT_EQ(fs::status(path).permissions(), fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
}

TEST_F(MapStoreTest, AMapCannotHoldSubmapsOneFileCannotHold) {
  SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 16, 3);
  MapParams same = map.params();
  SubmapInfo duplicate;
  duplicate.id = 3;
  EXPECT_THROW(map.add_finished_submap(duplicate, VoxelMap(same)), Error);
  MapParams other = map.params();
  other.semantic.dim = 8;
  SubmapInfo fresh;
  fresh.id = 9;
  EXPECT_THROW(map.add_finished_submap(fresh, VoxelMap(other)), Error);
  EXPECT_EQ(map.num_submaps(), 2u);
}

TEST_F(MapStoreTest, BadFilesGiveErrorsWithPathAndReason) {
  const fs::path good = dir_ / "good.svdb";
  save_map(good, make_map(EmbeddingPrecision::kFloat16, 64, 4));
  const std::string bytes = read_bytes(good);

  const fs::path missing = dir_ / "missing.svdb";
  std::string msg = load_error(missing);
  EXPECT_NE(msg.find(missing.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("no such file"), std::string::npos) << msg;

  const fs::path text = dir_ / "text.svdb";
  write_bytes(text, std::string(5000, 'x'));
  msg = load_error(text);
  EXPECT_NE(msg.find(text.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("not an SQLite database"), std::string::npos) << msg;

  const fs::path empty = dir_ / "empty.svdb";
  write_bytes(empty, "");
  EXPECT_NE(load_error(empty).find("not a slamvdb map"), std::string::npos);

  const fs::path cut = dir_ / "cut.svdb";
  write_bytes(cut, bytes.substr(0, bytes.size() / 2));
  msg = load_error(cut);
  EXPECT_NE(msg.find(cut.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("damaged or truncated"), std::string::npos) << msg;
  EXPECT_THROW(read_map_summary(cut), Error);

  const fs::path foreign = dir_ / "foreign.svdb";
  write_bytes(foreign, bytes);
  set_pragma(foreign, "application_id = 42");
  msg = load_error(foreign);
  EXPECT_NE(msg.find("not a slamvdb map"), std::string::npos) << msg;
  EXPECT_NE(msg.find(foreign.string()), std::string::npos) << msg;

  const fs::path newer = dir_ / "newer.svdb";
  write_bytes(newer, bytes);
  set_pragma(newer, fmt::format("user_version = {}", kMapFormatVersion + 1));
  msg = load_error(newer);
  EXPECT_NE(msg.find(fmt::format("map format version {} is newer than this slamvdb supports ({}); upgrade slamvdb",
                                 kMapFormatVersion + 1, kMapFormatVersion)),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find(newer.string()), std::string::npos) << msg;
  EXPECT_THROW(read_map_summary(newer), Error);
}

// Wherever a file is cut, loading either fails with an Error or (when only unused page space was
// cut off) returns exactly the saved map: never a crash, never a partial map.
TEST_F(MapStoreTest, TruncationAnywhereNeverYieldsAPartialMap) {
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 64, 7);
  const fs::path good = dir_ / "good.svdb";
  save_map(good, map);
  const std::string bytes = read_bytes(good);
  std::vector<std::size_t> cuts = {0, 1, 100, bytes.size() - 1, bytes.size() - 2000};
  for (int k = 1; k < 24; ++k) cuts.push_back(bytes.size() * k / 24);
  int failed = 0;
  for (const std::size_t n : cuts) {
    const fs::path cut = dir_ / "cut.svdb";
    write_bytes(cut, bytes.substr(0, n));
    try {
      const SemanticMap loaded = load_map(cut);
      expect_identical(map, loaded);
    } catch (const Error& e) {
      ++failed;
      EXPECT_NE(std::string(e.what()).find(cut.string()), std::string::npos) << e.what();
    }
  }
  EXPECT_GE(failed, 24);  // all but cuts inside the unused tail of the last page
}

// Finds `pattern` in the file, flips one byte inside it and expects the CRC check to catch it.
void expect_crc_error_after_flip(const fs::path& good, const fs::path& bad, const std::string& pattern,
                                 const std::string& what) {
  std::string bytes = read_bytes(good);
  const std::size_t at = bytes.find(pattern);
  ASSERT_NE(at, std::string::npos) << what << " pattern not found in the file";
  ASSERT_EQ(bytes.find(pattern, at + 1), std::string::npos) << what << " pattern is not unique";
  bytes[at + pattern.size() / 2] ^= 0x10;
  write_bytes(bad, bytes);
  const std::string msg = load_error(bad);
  EXPECT_NE(msg.find("CRC mismatch in " + what), std::string::npos) << msg;
  EXPECT_NE(msg.find(bad.string()), std::string::npos) << msg;
}

TEST_F(MapStoreTest, FlippedBytesInsideBlobsFailTheCrc) {
  // Recognisable values: a block of distinct log-odds and one embedding of distinct halves.
  std::array<float, 16> lo_pattern;
  for (int i = 0; i < 16; ++i) lo_pattern[i] = 1.0f + 0.0625f * i + 1e-6f;
  std::vector<float> e(64);
  std::string half_pattern;
  for (int i = 0; i < 64; ++i) {
    e[i] = 1000.0f + 3.0f * i;
    const uint16_t h = float_to_half(e[i]);
    if (i < 16) half_pattern.append(reinterpret_cast<const char*>(&h), 2);
  }
  const SemanticMap map = make_map(EmbeddingPrecision::kFloat16, 64, 5, [&](int id, VoxelMap& voxels) {
    if (id == -7)
      for (int i = 0; i < 16; ++i) voxels.occupancy().set_log_odds(voxel_of(BlockKey{500, 0, 0}, i), lo_pattern[i]);
    if (id == 3) voxels.semantics().set({7, 7, 7}, e.data(), 3);
  });
  const fs::path good = dir_ / "good.svdb";
  save_map(good, map);
  // Occupancy blobs are compressed: find the stored bytes of that block through SQLite.
  std::string block_blob;
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open_v2(good.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
    sqlite3_stmt* stmt = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "SELECT log_odds FROM occupancy WHERE submap = -7 AND bx = 500", -1, &stmt, nullptr),
              SQLITE_OK);
    ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
    block_blob.assign(static_cast<const char*>(sqlite3_column_blob(stmt, 0)), sqlite3_column_bytes(stmt, 0));
    sqlite3_finalize(stmt);
    sqlite3_close(db);
  }
  expect_crc_error_after_flip(good, dir_ / "bad_occupancy.svdb", block_blob, "occupancy block (500, 0, 0) of submap -7");
  expect_crc_error_after_flip(good, dir_ / "bad_semantics.svdb", half_pattern, "semantic chunk 0 of submap 3");
  // (the source is in the sessions table too; the model id only in meta)
  expect_crc_error_after_flip(good, dir_ / "bad_meta.svdb", map.info().model_id, "meta entry 'model_id'");
}

}  // namespace
}  // namespace slamvdb
