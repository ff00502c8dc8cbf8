// A map file whose checksums are right but whose content is impossible is refused, with the first
// problem named; version-1 files (one submap, no time ranges, no chunk column) still load.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <zlib.h>

#include <sys/wait.h>

#include <array>
#include <cmath>
#include <limits>

#include "slamvdb/core/half.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using namespace slamvdb::testing;

// The file format's CRC, as a tool that edits a file would recompute it.
struct Crc32 {
  uLong v = crc32(0L, Z_NULL, 0);
  Crc32& add(const void* p, std::size_t n) {
    v = crc32_z(v, static_cast<const Bytef*>(p), n);
    return *this;
  }
  Crc32& add(int64_t x) { return add(&x, sizeof x); }
  Crc32& add_real(double x) { return add(&x, sizeof x); }
  Crc32& add(const std::string& bytes) { return add(bytes.data(), bytes.size()); }
  int64_t value() const { return static_cast<int64_t>(v); }
};

class Db {
 public:
  explicit Db(const fs::path& p) { EXPECT_EQ(sqlite3_open(p.c_str(), &db_), SQLITE_OK); }
  ~Db() { sqlite3_close(db_); }
  void exec(const std::string& sql) { ASSERT_EQ(sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sql; }
  // Runs `sql` (one row), returning its columns as byte strings or numbers via the callback.
  sqlite3_stmt* prepare(const std::string& sql) {
    sqlite3_stmt* s = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db_, sql.c_str(), -1, &s, nullptr), SQLITE_OK) << sql;
    return s;
  }
  static std::string blob(sqlite3_stmt* s, int col) {
    return {static_cast<const char*>(sqlite3_column_blob(s, col)), static_cast<std::size_t>(sqlite3_column_bytes(s, col))};
  }

 private:
  sqlite3* db_ = nullptr;
};

// Rewrites the first semantic chunk of submap `id` through `edit(keys, counts, embeddings)` and
// recomputes its CRC, as a buggy tool would.
void edit_first_chunk(const fs::path& file, int id, const std::function<void(std::string&, std::string&, std::string&)>& edit) {
  Db db(file);
  sqlite3_stmt* s = db.prepare(fmt::format("SELECT rowid, chunk, keys, counts, embeddings FROM semantics WHERE submap = {} "
                                           "ORDER BY chunk LIMIT 1", id));
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  const int64_t rowid = sqlite3_column_int64(s, 0), chunk = sqlite3_column_int64(s, 1);
  std::string keys = Db::blob(s, 2), counts = Db::blob(s, 3), embeddings = Db::blob(s, 4);
  sqlite3_finalize(s);
  edit(keys, counts, embeddings);
  const int64_t crc = Crc32().add(int64_t{id}).add(chunk).add(keys).add(counts).add(embeddings).value();
  sqlite3_stmt* u = db.prepare("UPDATE semantics SET keys = ?, counts = ?, embeddings = ?, crc = ? WHERE rowid = ?");
  sqlite3_bind_blob(u, 1, keys.data(), static_cast<int>(keys.size()), SQLITE_TRANSIENT);
  sqlite3_bind_blob(u, 2, counts.data(), static_cast<int>(counts.size()), SQLITE_TRANSIENT);
  sqlite3_bind_blob(u, 3, embeddings.data(), static_cast<int>(embeddings.size()), SQLITE_TRANSIENT);
  sqlite3_bind_int64(u, 4, crc);
  sqlite3_bind_int64(u, 5, rowid);
  ASSERT_EQ(sqlite3_step(u), SQLITE_DONE);
  sqlite3_finalize(u);
}

void set_meta(const fs::path& file, const std::string& key, const std::string& value) {
  Db db(file);
  std::string k0 = key;
  k0.push_back('\0');
  const int64_t crc = Crc32().add(k0).add(value).value();
  db.exec(fmt::format("UPDATE meta SET value = '{}', crc = {} WHERE key = '{}'", value, crc, key));
}

// Replaces the pose of submap `id` (recomputing the row's CRC).
void set_pose(const fs::path& file, int id, const Eigen::Matrix4d& m) {
  Db db(file);
  sqlite3_stmt* s = db.prepare(fmt::format("SELECT time_begin, time_end, path_length, blocks, known_voxels, occupied_voxels, "
                                           "semantic_voxels FROM submaps WHERE id = {}", id));
  ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
  Crc32 crc;
  crc.add(int64_t{id}).add(m.data(), 128).add_real(sqlite3_column_double(s, 0)).add_real(sqlite3_column_double(s, 1));
  crc.add_real(sqlite3_column_double(s, 2));
  for (int c = 3; c < 7; ++c) crc.add(static_cast<int64_t>(sqlite3_column_int64(s, c)));
  sqlite3_finalize(s);
  sqlite3_stmt* u = db.prepare("UPDATE submaps SET pose = ?, crc = ? WHERE id = ?");
  sqlite3_bind_blob(u, 1, m.data(), 128, SQLITE_TRANSIENT);
  sqlite3_bind_int64(u, 2, crc.value());
  sqlite3_bind_int64(u, 3, id);
  ASSERT_EQ(sqlite3_step(u), SQLITE_DONE);
  sqlite3_finalize(u);
}

class MapValidationTest : public MapStoreTest {
 protected:
  // A fresh copy of a valid fp16 map for each damage.
  fs::path good_copy(const std::string& name) {
    if (good_.empty()) {
      good_ = dir_ / "good.svdb";
      save_map(good_, make_map(EmbeddingPrecision::kFloat16, 16, 21));
    }
    const fs::path p = dir_ / name;
    fs::copy_file(good_, p, fs::copy_options::overwrite_existing);
    return p;
  }
  void expect_refused(const fs::path& p, const std::string& why) {
    const std::string msg = load_error(p);
    EXPECT_NE(msg.find(why), std::string::npos) << "expected \"" << why << "\" in: " << msg;
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  }
  fs::path good_;
};

TEST_F(MapValidationTest, ImpossibleContentWithRightChecksumsIsRefused) {
  fs::path p = good_copy("nan.svdb");
  edit_first_chunk(p, 3, [](std::string&, std::string&, std::string& e) { e[0] = 0x00, e[1] = 0x7e; });  // fp16 NaN
  expect_refused(p, "non-finite embeddings");

  p = good_copy("zero_count.svdb");
  edit_first_chunk(p, 3, [](std::string&, std::string& c, std::string&) { std::fill_n(c.begin(), 4, '\0'); });
  expect_refused(p, "zero count");

  p = good_copy("duplicate_key.svdb");
  edit_first_chunk(p, 3, [](std::string& k, std::string&, std::string&) { k.replace(12, 12, k.substr(0, 12)); });
  expect_refused(p, "appears twice");

  p = good_copy("far_key.svdb");
  edit_first_chunk(p, 3, [](std::string& k, std::string&, std::string&) {
    const int32_t far = std::numeric_limits<int32_t>::max();
    std::memcpy(k.data(), &far, 4);
  });
  expect_refused(p, "outside the representable extent");

  p = good_copy("zero_pose.svdb");
  set_pose(p, 3, Eigen::Matrix4d::Zero());
  expect_refused(p, "not a rigid transform");
  p = good_copy("scaled_pose.svdb");
  set_pose(p, 3, Eigen::Matrix4d::Identity() * 2.0);
  expect_refused(p, "not a rigid transform");
  p = good_copy("far_pose.svdb");
  Eigen::Matrix4d far = Eigen::Matrix4d::Identity();
  far(0, 3) = 1e300;
  set_pose(p, 3, far);
  expect_refused(p, "outside any map");

  for (const auto& [key, value, why] : {std::tuple{"voxel_size", "1e-300", "outside 0.001..1000"},
                                        std::tuple{"voxel_size", "1e300", "outside 0.001..1000"},
                                        std::tuple{"semantic_dim", "0", "outside 1..16384"},
                                        std::tuple{"semantic_dim", "-1", "outside 1..16384"},
                                        std::tuple{"semantic_dim", "2147483647", "outside 1..16384"},
                                        std::tuple{"clamp_max", "nan", "is not finite"}}) {
    p = good_copy("meta.svdb");
    set_meta(p, key, value);
    expect_refused(p, why);
    EXPECT_THROW(read_map_summary(p), Error);  // the summary checks what it reads, too
  }

  p = good_copy("orphan.svdb");
  {
    Db db(p);
    db.exec("UPDATE semantics SET submap = 99 WHERE submap = 3");  // (CRC now wrong too, but orphans come first)
  }
  expect_refused(p, "refers to submap 99, which is not in the file");
}

// The colour basis a map is drawn in is saved bit-exactly and checked like every other value.
TEST_F(MapValidationTest, ColourBasisRoundTripsExactlyAndIsChecked) {
  SemanticMap m = make_map(EmbeddingPrecision::kFloat16, 16, 21);
  ColourBasis basis;
  basis.mean = Eigen::VectorXf::LinSpaced(16, -0.3f, 0.7f);
  basis.components = Eigen::Matrix<float, 3, Eigen::Dynamic>::Random(3, 16);
  basis.components.rowwise().normalize();
  basis.lo << -0.123456789f, -1.f / 3.f, 0.f;
  basis.hi << 0.987654321f, 2.f / 3.f, 1e-7f;
  MapInfo info = m.info();
  info.colour_basis = basis;
  m.set_info(info);
  const fs::path p = dir_ / "basis.svdb";
  save_map(p, m);
  for (const MapInfo& loaded : {load_map(p).info(), read_map_summary(p).info}) {
    ASSERT_TRUE(loaded.colour_basis.has_value());
    EXPECT_EQ(loaded.colour_basis->mean, basis.mean);
    EXPECT_EQ(loaded.colour_basis->components, basis.components);
    EXPECT_TRUE((loaded.colour_basis->lo == basis.lo).all());
    EXPECT_TRUE((loaded.colour_basis->hi == basis.hi).all());
  }
  // Maps without one (saved before bases were recorded) load without one.
  EXPECT_FALSE(load_map(good_copy("plain.svdb")).info().colour_basis.has_value());

  std::string text;
  {
    Db db(p);
    sqlite3_stmt* s = db.prepare("SELECT value FROM meta WHERE key = 'colour_basis'");
    ASSERT_EQ(sqlite3_step(s), SQLITE_ROW);
    text = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
    sqlite3_finalize(s);
  }
  const std::string rest = text.substr(text.find(' '));  // everything after the dimension
  for (const auto& [value, why] : {std::pair{"8" + rest, "for 8-d embeddings, the map's are 16-d"},
                                   std::pair{text + " 1", "more numbers than its dimension"},
                                   std::pair{text.substr(0, text.size() / 2), "not a list of numbers"},
                                   std::pair{std::string("16 x"), "not a list of numbers"}}) {
    const fs::path bad = dir_ / "bad_basis.svdb";
    fs::copy_file(p, bad, fs::copy_options::overwrite_existing);
    set_meta(bad, "colour_basis", value);
    expect_refused(bad, why);
  }
  // Impossible values, written as a buggy writer would.
  for (const auto& [edit, why] : std::vector<std::pair<std::function<void(ColourBasis&)>, std::string>>{
           {[](ColourBasis& b) { b.mean[3] = NAN; }, "non-finite"},
           {[](ColourBasis& b) { b.components(1, 0) = INFINITY; }, "non-finite"},
           {[](ColourBasis& b) { b.components.row(2) *= 2.f; }, "axis 2 has length 2"},
           {[](ColourBasis& b) { b.lo[0] = 5.f; }, "lo 5 above hi"}}) {
    ColourBasis b = basis;
    edit(b);
    info.colour_basis = b;
    m.set_info(info);
    const fs::path bad = dir_ / "bad_values.svdb";
    save_map(bad, m);
    expect_refused(bad, why);
  }
}

// `info` reads summaries only; `info --check` loads and validates everything.
TEST_F(MapValidationTest, InfoCheckRunsTheFullValidation) {
  const fs::path good = good_copy("ok.svdb"), bad = good_copy("bad.svdb");
  edit_first_chunk(bad, 3, [](std::string&, std::string&, std::string& e) { e[0] = 0x00, e[1] = 0x7c; });  // fp16 Inf
  auto run = [](const std::string& args) {
    const std::string cmd = std::string("'") + SLAMVDB_CLI_PATH + "' " + args + " 2>&1";
    FILE* pipe = popen(cmd.c_str(), "r");
    std::string out;
    char buf[4096];
    while (const std::size_t n = std::fread(buf, 1, sizeof buf, pipe)) out.append(buf, n);
    const int status = pclose(pipe);
    return std::pair{WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
  };
  const auto [ok_code, ok_out] = run("info --check '" + good.string() + "'");
  EXPECT_EQ(ok_code, 0) << ok_out;
  EXPECT_NE(ok_out.find("check      OK"), std::string::npos) << ok_out;
  EXPECT_EQ(run("info '" + bad.string() + "'").first, 0);  // the summary cannot see it
  const auto [bad_code, bad_out] = run("info --check '" + bad.string() + "'");
  EXPECT_EQ(bad_code, 1) << bad_out;
  EXPECT_NE(bad_out.find("non-finite embeddings"), std::string::npos) << bad_out;
}

// A version-1 file: one submap, the v1 schema and CRCs, written here the way slamvdb 0.1 wrote it.
void write_v1_file(const fs::path& path, const MapParams& params, const VoxelMap& voxels) {
  Db db(path);
  db.exec("PRAGMA application_id = 1398162498; PRAGMA user_version = 1;");
  db.exec(R"(CREATE TABLE meta(key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE submaps(id INTEGER NOT NULL UNIQUE, pose BLOB NOT NULL, blocks INTEGER NOT NULL,
  known_voxels INTEGER NOT NULL, occupied_voxels INTEGER NOT NULL, semantic_voxels INTEGER NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE occupancy(submap INTEGER NOT NULL, bx INTEGER NOT NULL, by INTEGER NOT NULL, bz INTEGER NOT NULL,
  log_odds BLOB NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE semantics(submap INTEGER NOT NULL, keys BLOB NOT NULL, counts BLOB NOT NULL, embeddings BLOB NOT NULL,
  crc INTEGER NOT NULL);)");
  const OccupancyParams& o = params.occupancy;
  const std::vector<std::pair<std::string, std::string>> meta = {
      {"voxel_size", fmt::format("{}", o.voxel_size)}, {"log_odds_hit", fmt::format("{}", o.log_odds_hit)},
      {"log_odds_miss", fmt::format("{}", o.log_odds_miss)}, {"clamp_min", fmt::format("{}", o.clamp_min)},
      {"clamp_max", fmt::format("{}", o.clamp_max)}, {"occupied_threshold", fmt::format("{}", o.occupied_threshold)},
      {"min_point_range", fmt::format("{}", o.min_point_range)}, {"max_point_range", fmt::format("{}", o.max_point_range)},
      {"max_clearing_range", fmt::format("{}", o.max_clearing_range)}, {"semantic_dim", std::to_string(params.semantic.dim)},
      {"semantic_precision", "fp16"}, {"format_version", "1"}, {"model_id", "v1-model"}, {"ontology", "rellis3d"},
      {"source", "a version-1 map"}, {"memory_bytes", "0"}, {"occupancy_payload_bytes", "0"}, {"semantic_payload_bytes", "0"}};
  for (const auto& [k, v] : meta) {
    std::string k0 = k;
    k0.push_back('\0');
    db.exec(fmt::format("INSERT INTO meta VALUES('{}', '{}', {})", k, v, Crc32().add(k0).add(v).value()));
  }
  const Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  const auto& grid = voxels.occupancy();
  const auto& layer = voxels.semantics();
  const int64_t crc = Crc32().add(int64_t{0}).add(pose.data(), 128).add(static_cast<int64_t>(grid.num_blocks()))
                          .add(static_cast<int64_t>(grid.num_known_voxels())).add(static_cast<int64_t>(grid.num_occupied_voxels()))
                          .add(static_cast<int64_t>(layer.size())).value();
  sqlite3_stmt* s = db.prepare("INSERT INTO submaps VALUES(0, ?, ?, ?, ?, ?, ?)");
  sqlite3_bind_blob(s, 1, pose.data(), 128, SQLITE_TRANSIENT);
  sqlite3_bind_int64(s, 2, static_cast<int64_t>(grid.num_blocks()));
  sqlite3_bind_int64(s, 3, static_cast<int64_t>(grid.num_known_voxels()));
  sqlite3_bind_int64(s, 4, static_cast<int64_t>(grid.num_occupied_voxels()));
  sqlite3_bind_int64(s, 5, static_cast<int64_t>(layer.size()));
  sqlite3_bind_int64(s, 6, crc);
  ASSERT_EQ(sqlite3_step(s), SQLITE_DONE);
  sqlite3_finalize(s);
  for (const auto& [bk, block] : grid.blocks()) {
    std::array<float, kBlockVoxels> lo;
    for (int i = 0; i < kBlockVoxels; ++i) lo[i] = block->cells[i].log_odds;
    std::string z(compressBound(sizeof lo), '\0');
    uLongf n = z.size();
    compress2(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(lo.data()), sizeof lo, 1);
    z.resize(n);
    sqlite3_stmt* b = db.prepare("INSERT INTO occupancy VALUES(0, ?, ?, ?, ?, ?)");
    sqlite3_bind_int64(b, 1, bk.x()), sqlite3_bind_int64(b, 2, bk.y()), sqlite3_bind_int64(b, 3, bk.z());
    sqlite3_bind_blob(b, 4, z.data(), static_cast<int>(z.size()), SQLITE_TRANSIENT);
    sqlite3_bind_int64(b, 5, Crc32().add(int64_t{0}).add(int64_t{bk.x()}).add(int64_t{bk.y()}).add(int64_t{bk.z()}).add(z).value());
    ASSERT_EQ(sqlite3_step(b), SQLITE_DONE);
    sqlite3_finalize(b);
  }
  std::string keys, counts, embeddings;
  layer.for_each([&](SemanticLayer::Handle h) {
    const VoxelKey& k = layer.key_of(h);
    const int32_t xyz[3] = {k.x(), k.y(), k.z()};
    const uint32_t n = layer.count_of(h);
    keys.append(reinterpret_cast<const char*>(xyz), 12);
    counts.append(reinterpret_cast<const char*>(&n), 4);
    embeddings.append(static_cast<const char*>(layer.embedding_of(h).data), 2 * static_cast<std::size_t>(layer.dim()));
  });
  sqlite3_stmt* e = db.prepare("INSERT INTO semantics VALUES(0, ?, ?, ?, ?)");
  sqlite3_bind_blob(e, 1, keys.data(), static_cast<int>(keys.size()), SQLITE_TRANSIENT);
  sqlite3_bind_blob(e, 2, counts.data(), static_cast<int>(counts.size()), SQLITE_TRANSIENT);
  sqlite3_bind_blob(e, 3, embeddings.data(), static_cast<int>(embeddings.size()), SQLITE_TRANSIENT);
  sqlite3_bind_int64(e, 4, Crc32().add(int64_t{0}).add(keys).add(counts).add(embeddings).value());
  ASSERT_EQ(sqlite3_step(e), SQLITE_DONE);
  sqlite3_finalize(e);
}

TEST_F(MapValidationTest, Version1FilesStillLoad) {
  MapParams params;
  params.semantic = {16, EmbeddingPrecision::kFloat16};
  VoxelMap voxels(params);
  std::vector<float> e(16);
  for (int x = 0; x < 40; ++x) {
    voxels.occupancy().set_log_odds({x, -x, 2}, 1.5f);
    voxels.occupancy().set_log_odds({x, -x, 3}, -0.5f);
    for (int c = 0; c < 16; ++c) e[c] = 0.01f * (x + c);
    if (x % 3) voxels.semantics().set({x, -x, 2}, e.data(), 1 + x);
  }
  const fs::path v1 = dir_ / "v1.svdb";
  write_v1_file(v1, params, voxels);
  const MapFileSummary summary = read_map_summary(v1);
  EXPECT_EQ(summary.format_version, 1);
  EXPECT_EQ(summary.params.submap_length, 0.0);  // a version-1 map is one submap
  ASSERT_EQ(summary.submaps.size(), 1u);
  EXPECT_TRUE(summary.submaps[0].info.time_range.empty());
  const SemanticMap map = load_map(v1);
  EXPECT_EQ(map.info().model_id, "v1-model");
  EXPECT_EQ(map.num_semantic_voxels(), voxels.semantics().size());
  EXPECT_EQ(map.num_known_voxels(), 80u);
  std::vector<float> scratch(16), got(16);
  map.read_index([&](const GlobalIndex& index) {
    EXPECT_EQ(index.size(), voxels.semantics().size());
    const auto cell = index.read_at(center_of_key(VoxelKey(7, -7, 2), 0.25), scratch.data());
    ASSERT_TRUE(cell);
    EXPECT_EQ(cell->count, 8u);
    kernels::decode(cell->embedding, got.data(), 16);
    for (int c = 0; c < 16; ++c) EXPECT_NEAR(got[c], 0.01f * (7 + c), 1e-3f);
  });
  // Saved again, it is a version-2 file with the same content.
  save_map(dir_ / "v2.svdb", map);
  EXPECT_EQ(read_map_summary(dir_ / "v2.svdb").format_version, kMapFormatVersion);
  expect_identical(map, load_map(dir_ / "v2.svdb"));
}

}  // namespace
}  // namespace slamvdb
