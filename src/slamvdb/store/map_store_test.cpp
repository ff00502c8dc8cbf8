#include "slamvdb/store/map_store.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

class MapStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("slamvdb_map_store_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

Pose make_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Two submaps with negative keys, boundary and odd float values (-0, subnormal, NaN with a payload,
// an all-unknown block) and embeddings with subnormal, signed-zero and extreme fp16 values.
SemanticMap make_map(EmbeddingPrecision precision, int dim, int seed,
                     const std::function<void(int id, VoxelMap&)>& edit = {}) {
  MapParams params;
  params.occupancy.voxel_size = 0.2;
  params.occupancy.clamp_max = 3.25f;
  params.semantic = {dim, precision};
  SemanticMap map(params, {"simulated-clip-test", "rellis3d", "SIMULATED unit-test map, seed " + std::to_string(seed)});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> lo(-2.0f, 3.25f), unit(-1.0f, 1.0f);
  std::uniform_int_distribution<int> coord(-40, 40);
  std::uniform_int_distribution<uint32_t> count(1, 100000);
  std::vector<float> e(dim);
  for (const auto& [id, pose, t0] : {std::tuple{3, make_pose(0.3, {1.5, -2.25, 0.125}), 10.0},
                                      std::tuple{-7, make_pose(-2.0, {100.0, 40.0, -3.0}), 20.0}}) {
    VoxelMap voxels(params);
    OccupancyGrid& grid = voxels.occupancy();
    for (int i = 0; i < 3000; ++i) grid.set_log_odds({coord(rng), coord(rng), coord(rng)}, lo(rng));
    grid.set_log_odds({-1, -1, -1}, -0.0f);
    grid.set_log_odds({-2, -1, -1}, std::numeric_limits<float>::denorm_min());
    grid.set_log_odds({-3, -1, -1}, std::bit_cast<float>(0x7fc00123u));  // unknown, unusual NaN bits
    grid.set_log_odds({800, 800, 800}, std::numeric_limits<float>::quiet_NaN());  // a block with no known voxel
    SemanticLayer& layer = voxels.semantics();
    int n = 0;
    grid.for_each_occupied([&](const VoxelKey& k, float) {
      if (n++ % 2) return;
      for (float& x : e) x = unit(rng);
      layer.set(k, e.data(), count(rng));
    });
    e.assign(dim, 0.0f);
    e[0] = -0.0f, e[1] = 65504.0f, e[2] = 6e-8f, e[3] = -1e-5f;
    layer.set({-1, -1, -1}, e.data(), UINT32_MAX);
    SubmapInfo info;
    info.id = id;
    info.T_world_submap = pose;
    info.time_range = {t0, t0 + 4.5};
    info.path_length = 12.5;
    if (edit) edit(id, voxels);
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

void expect_same_params(const MapParams& a, const MapParams& b) {
  EXPECT_EQ(a.occupancy.voxel_size, b.occupancy.voxel_size);
  EXPECT_EQ(a.occupancy.log_odds_hit, b.occupancy.log_odds_hit);
  EXPECT_EQ(a.occupancy.log_odds_miss, b.occupancy.log_odds_miss);
  EXPECT_EQ(a.occupancy.clamp_min, b.occupancy.clamp_min);
  EXPECT_EQ(a.occupancy.clamp_max, b.occupancy.clamp_max);
  EXPECT_EQ(a.occupancy.occupied_threshold, b.occupancy.occupied_threshold);
  EXPECT_EQ(a.occupancy.min_point_range, b.occupancy.min_point_range);
  EXPECT_EQ(a.occupancy.max_point_range, b.occupancy.max_point_range);
  EXPECT_EQ(a.occupancy.max_clearing_range, b.occupancy.max_clearing_range);
  EXPECT_EQ(a.semantic.dim, b.semantic.dim);
  EXPECT_EQ(a.semantic.precision, b.semantic.precision);
}

// Bit-level comparison: every log-odds (NaN payloads included) and every embedding value.
void expect_identical(const SemanticMap& a, const SemanticMap& b) {
  expect_same_params(a.params(), b.params());
  EXPECT_EQ(a.params().submap_length, b.params().submap_length);
  EXPECT_EQ(a.info().model_id, b.info().model_id);
  EXPECT_EQ(a.info().ontology, b.info().ontology);
  EXPECT_EQ(a.info().source, b.info().source);
  const auto infos_a = a.submaps(), infos_b = b.submaps();
  ASSERT_EQ(infos_a.size(), infos_b.size());
  for (std::size_t i = 0; i < infos_a.size(); ++i) {
    const SubmapInfo &ia = infos_a[i], &ib = infos_b[i];
    EXPECT_EQ(ia.id, ib.id);
    EXPECT_EQ(ia.T_world_submap.matrix(), ib.T_world_submap.matrix());
    EXPECT_EQ(ia.time_range.begin, ib.time_range.begin);
    EXPECT_EQ(ia.time_range.end, ib.time_range.end);
    EXPECT_EQ(ia.path_length, ib.path_length);
    a.read_submap(ia.id, [&](const Submap& sa) {
      b.read_submap(ib.id, [&](const Submap& sb) {
        expect_same_params(sa.voxels().params(), sb.voxels().params());
        const OccupancyGrid &ga = sa.voxels().occupancy(), &gb = sb.voxels().occupancy();
        ASSERT_EQ(ga.num_blocks(), gb.num_blocks());
        EXPECT_EQ(ga.num_occupied_voxels(), gb.num_occupied_voxels());
        for (const auto& [bk, block] : ga.blocks()) {
          const auto it = gb.blocks().find(bk);
          ASSERT_NE(it, gb.blocks().end()) << bk.transpose();
          for (int v = 0; v < kBlockVoxels; ++v) {
            ASSERT_EQ(std::bit_cast<uint32_t>(block->cells[v].log_odds),
                      std::bit_cast<uint32_t>(it->second->cells[v].log_odds))
                << "block " << bk.transpose() << " voxel " << v;
            ASSERT_EQ(block->occupied(v), it->second->occupied(v));
          }
        }
        const SemanticLayer &la = sa.voxels().semantics(), &lb = sb.voxels().semantics();
        ASSERT_EQ(la.size(), lb.size());
        std::vector<float> ea(la.dim()), eb(la.dim());
        la.for_each([&](SemanticLayer::Handle h) {
          const VoxelKey& k = la.key_of(h);
          const auto other = lb.find(k);
          ASSERT_TRUE(other) << k.transpose();
          EXPECT_EQ(la.count_of(h), lb.count_of(*other));
          la.read(h, ea.data());
          lb.read(*other, eb.data());
          ASSERT_EQ(std::memcmp(ea.data(), eb.data(), ea.size() * sizeof(float)), 0) << k.transpose();
        });
      });
    });
  }
}

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path().filename());
  std::sort(files.begin(), files.end());
  return files;
}

std::string load_error(const fs::path& path) {
  try {
    load_map(path);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "loading " << path << " did not throw";
  return {};
}

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

void set_pragma(const fs::path& file, const std::string& pragma) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, ("PRAGMA " + pragma).c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

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
  EXPECT_EQ(s.semantic_payload_bytes, map.num_semantic_voxels() * (12 + 4 + 32 * 2));
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
  set_pragma(newer, "user_version = 3");
  msg = load_error(newer);
  EXPECT_NE(msg.find("map format version 3 is newer than this slamvdb supports (2); upgrade slamvdb"),
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
  expect_crc_error_after_flip(good, dir_ / "bad_meta.svdb", map.info().source, "meta entry 'source'");
}

// A large map for the kill test: ~40 MB, so the save is still writing when the child is killed.
SemanticMap make_large_map() {
  MapParams params;
  params.semantic = {512, EmbeddingPrecision::kFloat16};
  SemanticMap map(params);
  VoxelMap voxels(params);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  std::vector<float> e(512);
  for (int x = 0; x < 200; ++x)
    for (int y = 0; y < 200; ++y) {
      const VoxelKey k(x, y, (x + y) / 16);
      voxels.occupancy().set_log_odds(k, 1.0f);
      for (float& v : e) v = unit(rng);
      voxels.semantics().set(k, e.data(), 1);
    }
  map.add_finished_submap({}, std::move(voxels));
  return map;
}

bool temp_file_at_least(const fs::path& dir, const std::string& prefix, uintmax_t bytes) {
  std::error_code ec;
  for (const auto& f : fs::directory_iterator(dir, ec))
    if (f.path().filename().string().starts_with(prefix) && fs::file_size(f.path(), ec) >= bytes && !ec) return true;
  return false;
}

TEST_F(MapStoreTest, SaveIsAtomicWhenKilledMidWrite) {
  const fs::path path = dir_ / "map.svdb";
  const SemanticMap previous = make_map(EmbeddingPrecision::kFloat16, 512, 6);
  save_map(path, previous);
  const std::string previous_bytes = read_bytes(path);
  const SemanticMap large = make_large_map();

  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    try {
      save_map(path, large);
    } catch (...) {
      _exit(3);
    }
    _exit(0);
  }
  // Kill the writer once its temp file holds a few megabytes: well into the save, before the rename.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!temp_file_at_least(dir_, ".map.svdb.tmp-", 4 << 20) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the save finished before the kill";

  // The killed save left its temp file, but the map is the previous one, byte for byte.
  const auto files = files_in(dir_);
  ASSERT_EQ(files.size(), 2u);
  EXPECT_TRUE(files[0].string().starts_with(".map.svdb.tmp-")) << files[0];
  EXPECT_EQ(read_bytes(path), previous_bytes);
  expect_identical(previous, load_map(path));

  // The next save replaces the map and removes the dead writer's temp file.
  save_map(path, large);
  EXPECT_EQ(files_in(dir_), std::vector<fs::path>{"map.svdb"});
  expect_identical(large, load_map(path));
}

// The numbers behind the storage choice (run with --gtest_also_run_disabled_tests): a
// terrain-like map of 200k occupied and 1M known voxels with 50k semantic voxels at 512-d fp16,
// embeddings clustered around 20 class prototypes.
TEST_F(MapStoreTest, DISABLED_LargeMapMeasurement) {
  using Clock = std::chrono::steady_clock;
  MapParams params;
  params.semantic = {512, EmbeddingPrecision::kFloat16};
  SemanticMap map(params, {"simulated-clip-512", "rellis3d", "SIMULATED measurement map"});
  VoxelMap voxels(params);
  OccupancyGrid& grid = voxels.occupancy();
  SemanticLayer& layer = voxels.semantics();
  std::mt19937 rng(11);
  // Log-odds as scans leave them: sums of a few hits or misses, clamped.
  const OccupancyParams& op = params.occupancy;
  std::uniform_int_distribution<int> updates(1, 8);
  auto occupied = [&](std::mt19937& r) { return std::min(op.clamp_max, updates(r) * op.log_odds_hit); };
  auto free = [&](std::mt19937& r) { return std::max(op.clamp_min, updates(r) * op.log_odds_miss); };
  std::normal_distribution<float> noise(0.0f, 0.3f);
  std::vector<std::vector<float>> prototypes(20, std::vector<float>(512));
  for (auto& p : prototypes)
    for (float& v : p) v = noise(rng);
  std::vector<float> e(512);
  const int side = 448;  // 448^2 = 200704 surface columns
  for (int x = 0; x < side; ++x)
    for (int y = 0; y < side; ++y) {
      const int z = static_cast<int>(std::lround(4.0 * std::sin(x / 37.0) + 3.0 * std::cos(y / 23.0)));
      grid.set_log_odds({x, y, z}, occupied(rng));
      for (int dz = 1; dz <= 4; ++dz) grid.set_log_odds({x, y, z + dz}, free(rng));
      if ((x + 2 * y) % 4 == 0) {
        const auto& p = prototypes[(x / 40 + y / 40) % prototypes.size()];
        for (int c = 0; c < 512; ++c) e[c] = p[c] + 0.3f * noise(rng);
        layer.set({x, y, z}, e.data(), 1 + rng() % 200);
      }
    }
  const std::size_t blocks = grid.num_blocks();
  map.add_finished_submap({}, std::move(voxels));
  const fs::path path = dir_ / "large.svdb";
  const auto t0 = Clock::now();
  const std::clock_t c0 = std::clock();
  save_map(path, map);
  const auto t1 = Clock::now();
  const std::clock_t c1 = std::clock();
  const SemanticMap loaded = load_map(path);
  const auto t2 = Clock::now();
  const std::clock_t c2 = std::clock();
  const MapFileSummary summary = read_map_summary(path);
  const auto t3 = Clock::now();
  expect_identical(map, loaded);
  const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  const double file = static_cast<double>(fs::file_size(path));
  const double semantic = static_cast<double>(map.num_semantic_voxels());
  std::printf(
      "known %zu occupied %zu semantic %zu blocks %zu\n"
      "save %.0f ms (cpu %.0f ms), load %.0f ms (cpu %.0f ms), summary %.1f ms\n"
      "file %.1f MB (in memory %.1f MB); occupancy payload %.1f MB, semantic payload %.1f MB\n"
      "bytes per semantic voxel: payload %.1f, whole file %.1f, file minus occupancy payload %.1f\n",
      map.num_known_voxels(), map.num_occupied_voxels(), map.num_semantic_voxels(), blocks, ms(t1 - t0),
      (c1 - c0) * 1e3 / CLOCKS_PER_SEC, ms(t2 - t1), (c2 - c1) * 1e3 / CLOCKS_PER_SEC, ms(t3 - t2), file / 1e6, map.memory_bytes() / 1e6, summary.occupancy_payload_bytes / 1e6,
      summary.semantic_payload_bytes / 1e6, summary.semantic_payload_bytes / semantic, file / semantic,
      (file - summary.occupancy_payload_bytes) / semantic);
  EXPECT_EQ(summary.semantic_voxels, map.num_semantic_voxels());
}

}  // namespace
}  // namespace slamvdb
