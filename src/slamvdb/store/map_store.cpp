#include "slamvdb/store/map_store.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sqlite3.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <span>
#include <string_view>
#include <tuple>
#include <unordered_map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace fs = std::filesystem;
namespace {

static_assert(std::endian::native == std::endian::little, "map blobs hold host-order numbers, which must be LE");

constexpr std::size_t kBlockBytes = OccupancyGrid::kBlockVoxels * sizeof(float);
// With SQLite's default 4 KiB pages only one 2 KiB occupancy row fits a page and every large blob
// is a long overflow chain: a measured map was 15% larger and saved 1.5x slower than with 64 KiB.
constexpr int kPageSize = 65536;
// Block keys are shifted by 3 bits into voxel keys, which must stay within int32.
constexpr int64_t kMaxBlockCoordinate = int64_t{1} << 27;

constexpr const char* kSchema = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE submaps(id INTEGER NOT NULL UNIQUE, pose BLOB NOT NULL, blocks INTEGER NOT NULL,
  known_voxels INTEGER NOT NULL, occupied_voxels INTEGER NOT NULL, semantic_voxels INTEGER NOT NULL,
  crc INTEGER NOT NULL);
CREATE TABLE occupancy(submap INTEGER NOT NULL, bx INTEGER NOT NULL, by INTEGER NOT NULL, bz INTEGER NOT NULL,
  log_odds BLOB NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE semantics(submap INTEGER NOT NULL, keys BLOB NOT NULL, counts BLOB NOT NULL,
  embeddings BLOB NOT NULL, crc INTEGER NOT NULL);
)sql";

std::string errno_text() { return std::strerror(errno); }

class Crc {
 public:
  Crc& add(const void* data, std::size_t n) {
    value_ = crc32_z(value_, static_cast<const Bytef*>(data), n);
    return *this;
  }
  Crc& add(int64_t v) { return add(&v, sizeof v); }
  Crc& add(std::span<const std::byte> bytes) { return add(bytes.data(), bytes.size()); }
  int64_t value() const { return static_cast<int64_t>(value_); }

 private:
  uLong value_ = crc32(0L, Z_NULL, 0);
};

Error sqlite_error(sqlite3* db, int rc) {
  const std::string msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_NOTADB: return Error("not an SQLite database, so not a slamvdb map (SQLite: " + msg + ")");
    case SQLITE_CORRUPT: return Error("the file is damaged or truncated (SQLite: " + msg + ")");
    default: return Error("SQLite: " + msg);
  }
}

class Database {
 public:
  Database(const fs::path& file, int flags) {
    const int rc = sqlite3_open_v2(file.c_str(), &db_, flags, nullptr);
    if (rc != SQLITE_OK) {
      const Error e = sqlite_error(db_, rc);
      sqlite3_close(db_);
      throw e;
    }
  }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  ~Database() { sqlite3_close(db_); }

  sqlite3* handle() const { return db_; }
  void exec(const std::string& sql) {
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr);
    if (rc != SQLITE_OK) throw sqlite_error(db_, rc);
  }
  // Closing reports what a destructor could not: the last write failing.
  void close() {
    const int rc = sqlite3_close(db_);
    if (rc != SQLITE_OK) throw sqlite_error(db_, rc);
    db_ = nullptr;
  }

 private:
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement(Database& db, const std::string& sql) : db_(db.handle()) {
    const int rc = sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt_, nullptr);
    if (rc != SQLITE_OK) throw sqlite_error(db_, rc);
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement() { sqlite3_finalize(stmt_); }

  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw sqlite_error(db_, rc);
  }
  void insert() {
    step();
    sqlite3_reset(stmt_);
  }
  Statement& bind(int i, int64_t v) { return check(sqlite3_bind_int64(stmt_, i, v)); }
  Statement& bind(int i, std::string_view s) {
    return check(sqlite3_bind_text64(stmt_, i, s.data(), s.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  // The bytes must stay valid until insert().
  Statement& bind(int i, std::span<const std::byte> b) {
    return check(sqlite3_bind_blob64(stmt_, i, b.data(), b.size(), SQLITE_STATIC));
  }
  int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  std::string text(int col) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col))) : std::string();
  }
  std::span<const std::byte> blob(int col) const {
    const auto* p = static_cast<const std::byte*>(sqlite3_column_blob(stmt_, col));
    return {p, p ? static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col)) : 0};
  }

 private:
  Statement& check(int rc) {
    if (rc != SQLITE_OK) throw sqlite_error(db_, rc);
    return *this;
  }
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

template <class T>
std::span<const std::byte> bytes_of(const T& container) {
  return std::as_bytes(std::span(container));
}

// ---- meta: parameters and info as text, numbers in their shortest exact form ----

using Meta = std::map<std::string, std::string, std::less<>>;

template <class Params, class F>  // Params = MapParams or const MapParams
void for_each_number(Params& p, F&& f) {
  f("voxel_size", p.occupancy.voxel_size);
  f("log_odds_hit", p.occupancy.log_odds_hit);
  f("log_odds_miss", p.occupancy.log_odds_miss);
  f("clamp_min", p.occupancy.clamp_min);
  f("clamp_max", p.occupancy.clamp_max);
  f("occupied_threshold", p.occupancy.occupied_threshold);
  f("min_point_range", p.occupancy.min_point_range);
  f("max_point_range", p.occupancy.max_point_range);
  f("max_clearing_range", p.occupancy.max_clearing_range);
  f("semantic_dim", p.semantic.dim);
}

Meta params_meta(const MapParams& params) {
  Meta meta;
  for_each_number(params, [&](const char* key, const auto& v) { meta[key] = fmt::format("{}", v); });
  meta["semantic_precision"] = std::string(to_string(params.semantic.precision));
  return meta;
}

const std::string& meta_value(const Meta& meta, const std::string& key) {
  const auto it = meta.find(key);
  if (it == meta.end()) throw Error(fmt::format("meta entry '{}' is missing", key));
  return it->second;
}

template <class T>
T parse_number(const Meta& meta, const std::string& key) {
  const std::string& text = meta_value(meta, key);
  T v{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size())
    throw Error(fmt::format("meta entry '{}' = '{}' is not a number", key, text));
  return v;
}

MapParams parse_params(const Meta& meta) {
  MapParams params;
  for_each_number(params, [&](const char* key, auto& v) { v = parse_number<std::decay_t<decltype(v)>>(meta, key); });
  params.semantic.precision = precision_from_string(meta_value(meta, "semantic_precision"));
  params.occupancy.validate();
  return params;
}

// ---- writing ----

std::vector<SubmapSummary> summarize_submaps(const SemanticMap& map) {
  std::vector<SubmapSummary> rows;
  for (const Submap& s : map.submaps)
    rows.push_back({s.id, s.T_world_submap, s.map.occupancy().num_blocks(), s.map.occupancy().num_known_voxels(),
                    s.map.occupancy().num_occupied_voxels(), s.map.semantics().size()});
  return rows;
}

void check_savable(const SemanticMap& map) {
  const Meta expected = params_meta(map.params);
  std::unordered_map<int, int> seen;
  for (const Submap& s : map.submaps) {
    if (!seen.emplace(s.id, 0).second) throw Error(fmt::format("two submaps have the id {}", s.id));
    if (params_meta(s.map.params()) != expected)
      throw Error(fmt::format("submap {} has map parameters different from the map's; one file holds one set", s.id));
    if (!s.T_world_submap.matrix().allFinite()) throw Error(fmt::format("submap {} has a non-finite pose", s.id));
  }
}

void write_meta(Database& db, const SemanticMap& map, uint64_t occupancy_payload_bytes) {
  Meta meta = params_meta(map.params);
  meta["format_version"] = std::to_string(kMapFormatVersion);
  meta["model_id"] = map.info.model_id;
  meta["ontology"] = map.info.ontology;
  meta["source"] = map.info.source;
  meta["memory_bytes"] = std::to_string(map.memory_bytes());
  const std::size_t embedding_bytes = static_cast<std::size_t>(map.params.semantic.dim) *
                                      (map.params.semantic.precision == EmbeddingPrecision::kFloat16 ? 2 : 4);
  meta["occupancy_payload_bytes"] = std::to_string(occupancy_payload_bytes);
  meta["semantic_payload_bytes"] =
      std::to_string(map.num_semantic_voxels() * (3 * sizeof(int32_t) + sizeof(uint32_t) + embedding_bytes));

  Statement insert(db, "INSERT INTO meta(key, value, crc) VALUES(?, ?, ?)");
  for (const auto& [key, value] : meta)
    insert.bind(1, key).bind(2, value).bind(3, Crc().add(key.data(), key.size() + 1).add(value.data(), value.size()).value())
        .insert();
}

int64_t submap_crc(const SubmapSummary& s, std::span<const std::byte> pose) {
  return Crc()
      .add(int64_t{s.id})
      .add(pose)
      .add(static_cast<int64_t>(s.blocks))
      .add(static_cast<int64_t>(s.known_voxels))
      .add(static_cast<int64_t>(s.occupied_voxels))
      .add(static_cast<int64_t>(s.semantic_voxels))
      .value();
}

void write_submaps(Database& db, const SemanticMap& map) {
  Statement insert(db,
                   "INSERT INTO submaps(id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc) "
                   "VALUES(?, ?, ?, ?, ?, ?, ?)");
  for (const SubmapSummary& s : summarize_submaps(map)) {
    const Eigen::Matrix4d pose = s.T_world_submap.matrix();  // column-major
    const auto pose_bytes = std::as_bytes(std::span(pose.data(), 16));
    insert.bind(1, int64_t{s.id}).bind(2, pose_bytes).bind(3, static_cast<int64_t>(s.blocks));
    insert.bind(4, static_cast<int64_t>(s.known_voxels)).bind(5, static_cast<int64_t>(s.occupied_voxels));
    insert.bind(6, static_cast<int64_t>(s.semantic_voxels)).bind(7, submap_crc(s, pose_bytes)).insert();
  }
}

bool key_less(const VoxelKey& a, const VoxelKey& b) {
  return std::tie(a.z(), a.y(), a.x()) < std::tie(b.z(), b.y(), b.x());
}

// Rows are written in key order so that the same map always gives the same file. Returns the bytes
// of the (compressed) blobs.
uint64_t write_occupancy(Database& db, const Submap& submap) {
  using Entry = OccupancyGrid::BlockMap::value_type;
  std::vector<const Entry*> blocks;
  for (const Entry& e : submap.map.occupancy().blocks()) blocks.push_back(&e);
  std::sort(blocks.begin(), blocks.end(), [](const Entry* a, const Entry* b) { return key_less(a->first, b->first); });

  Statement insert(db, "INSERT INTO occupancy(submap, bx, by, bz, log_odds, crc) VALUES(?, ?, ?, ?, ?, ?)");
  std::array<float, OccupancyGrid::kBlockVoxels> log_odds;
  std::vector<std::byte> compressed(compressBound(kBlockBytes));
  uint64_t payload = 0;
  for (const Entry* e : blocks) {
    const VoxelKey& bk = e->first;
    for (int i = 0; i < OccupancyGrid::kBlockVoxels; ++i) log_odds[i] = e->second->cells[i].log_odds;
    uLongf size = compressed.size();
    if (compress2(reinterpret_cast<Bytef*>(compressed.data()), &size, reinterpret_cast<const Bytef*>(log_odds.data()),
                  kBlockBytes, Z_BEST_SPEED) != Z_OK)
      throw Error("zlib failed to compress an occupancy block");
    const auto blob = std::span<const std::byte>(compressed.data(), size);
    payload += size;
    const int64_t crc = Crc().add(int64_t{submap.id}).add(bk.x()).add(bk.y()).add(bk.z()).add(blob).value();
    insert.bind(1, int64_t{submap.id}).bind(2, bk.x()).bind(3, bk.y()).bind(4, bk.z()).bind(5, blob).bind(6, crc);
    insert.insert();
  }
  return payload;
}

void write_semantics(Database& db, const Submap& submap) {
  const SemanticLayer& layer = submap.map.semantics();
  std::vector<std::pair<VoxelKey, SemanticLayer::Slot>> entries;
  entries.reserve(layer.size());
  layer.for_each([&](const VoxelKey& k, SemanticLayer::Slot s) { entries.emplace_back(k, s); });
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return key_less(a.first, b.first); });

  const auto dim = static_cast<std::size_t>(layer.dim());
  const bool fp16 = layer.precision() == EmbeddingPrecision::kFloat16;
  Statement insert(db, "INSERT INTO semantics(submap, keys, counts, embeddings, crc) VALUES(?, ?, ?, ?, ?)");
  std::vector<int32_t> keys;
  std::vector<uint32_t> counts;
  std::vector<float> fp32;
  std::vector<uint16_t> halves;
  std::vector<float> embedding(dim);
  for (std::size_t begin = 0; begin < entries.size(); begin += kSemanticChunkEntries) {
    const std::size_t n = std::min(kSemanticChunkEntries, entries.size() - begin);
    keys.resize(3 * n);
    counts.resize(n);
    if (fp16) halves.resize(n * dim);
    else fp32.resize(n * dim);
    for (std::size_t j = 0; j < n; ++j) {
      const auto& [key, slot] = entries[begin + j];
      std::copy_n(key.data(), 3, &keys[3 * j]);
      counts[j] = layer.count_at(slot);
      if (fp16) {
        // fp16 -> fp32 -> fp16 is exact for every non-NaN half, so the stored bits are the map's.
        layer.read(slot, embedding.data());
        for (std::size_t c = 0; c < dim; ++c) halves[j * dim + c] = float_to_half(embedding[c]);
      } else {
        layer.read(slot, &fp32[j * dim]);
      }
    }
    const auto key_bytes = bytes_of(keys), count_bytes = bytes_of(counts);
    const auto embedding_bytes = fp16 ? bytes_of(halves) : bytes_of(fp32);
    const int64_t crc = Crc().add(int64_t{submap.id}).add(key_bytes).add(count_bytes).add(embedding_bytes).value();
    insert.bind(1, int64_t{submap.id}).bind(2, key_bytes).bind(3, count_bytes).bind(4, embedding_bytes).bind(5, crc);
    insert.insert();
  }
}

void write_database(const fs::path& file, const SemanticMap& map) {
  Database db(file, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX);
  // No journal and no syncs: the file is private until the rename, and fsynced before it.
  db.exec(fmt::format(
      "PRAGMA page_size = {}; PRAGMA journal_mode = OFF; PRAGMA synchronous = OFF; PRAGMA locking_mode = EXCLUSIVE;"
      "PRAGMA application_id = {}; PRAGMA user_version = {};",
      kPageSize, kMapApplicationId, kMapFormatVersion));
  db.exec("BEGIN");
  db.exec(kSchema);
  write_submaps(db, map);
  uint64_t occupancy_payload_bytes = 0;
  for (const Submap& s : map.submaps) occupancy_payload_bytes += write_occupancy(db, s);
  for (const Submap& s : map.submaps) write_semantics(db, s);
  write_meta(db, map, occupancy_payload_bytes);
  db.exec("COMMIT");
  db.close();
}

// ---- the atomic replace ----

// Temp files are hidden siblings of the target named after the saving process, so a reader never
// takes one for a map and a later save can tell which ones a killed process left behind.
std::string temp_prefix(const fs::path& target) { return fmt::format(".{}.tmp-", target.filename().string()); }

class TempFile {
 public:
  // Created like any new file (mode 0666 minus the umask), or with the permissions of the map it replaces.
  explicit TempFile(const fs::path& target) {
    std::random_device random;
    for (int attempt = 0;; ++attempt) {
      const fs::path name = target.parent_path() / fmt::format("{}{}-{:08x}", temp_prefix(target), getpid(), random());
      const int fd = ::open(name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd >= 0) {
        ::close(fd);
        path_ = name;
        break;
      }
      if (errno != EEXIST || attempt == 100)
        throw Error(fmt::format("cannot create a temp file {}: {}", name.string(), errno_text()));
    }
    std::error_code ec;
    const fs::file_status previous = fs::status(target, ec);
    if (!ec && fs::is_regular_file(previous)) fs::permissions(path_, previous.permissions(), ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    std::error_code ignored;
    if (!path_.empty()) fs::remove(path_, ignored);
  }
  const fs::path& path() const { return path_; }
  void release() { path_.clear(); }

 private:
  fs::path path_;
};

void fsync_path(const fs::path& p, int flags) {
  const int fd = ::open(p.c_str(), flags | O_CLOEXEC);
  if (fd < 0) throw Error(fmt::format("cannot open {} to sync it: {}", p.string(), errno_text()));
  const int rc = ::fsync(fd);
  const std::string reason = rc != 0 ? errno_text() : std::string();
  ::close(fd);
  if (rc != 0) throw Error(fmt::format("fsync of {} failed: {}", p.string(), reason));
}

// Best effort: the map is already saved, a temp file that cannot be removed only wastes space.
void remove_stale_temp_files(const fs::path& target) {
  const std::string prefix = temp_prefix(target);
  std::error_code ec;
  for (auto it = fs::directory_iterator(target.parent_path(), ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.starts_with(prefix)) continue;
    int pid = 0;
    const char* digits = name.data() + prefix.size();
    const auto [end, err] = std::from_chars(digits, name.data() + name.size(), pid);
    if (err != std::errc() || *end != '-' || pid <= 0 || pid == getpid()) continue;
    if (::kill(pid, 0) == 0 || errno != ESRCH) continue;  // its writer may still be running
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

// ---- reading ----

int64_t pragma_value(Database& db, const char* name) {
  Statement s(db, fmt::format("PRAGMA {}", name));
  if (!s.step()) throw Error(fmt::format("PRAGMA {} returned nothing", name));
  return s.int64(0);
}

std::unique_ptr<Database> open_map(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw Error("no such file");
  if (!fs::is_regular_file(status)) throw Error("not a regular file");
  auto db = std::make_unique<Database>(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX);
  const int64_t application_id = pragma_value(*db, "application_id");  // a foreign file fails here
  if (application_id != kMapApplicationId)
    throw Error(fmt::format("not a slamvdb map (SQLite application_id {:#x}, expected {:#x})", application_id,
                            kMapApplicationId));
  const int64_t version = pragma_value(*db, "user_version");
  if (version > kMapFormatVersion)
    throw Error(fmt::format("map format version {} is newer than this slamvdb supports ({}); upgrade slamvdb",
                            version, kMapFormatVersion));
  if (version < 1) throw Error(fmt::format("invalid map format version {}", version));
  return db;
}

Meta read_meta(Database& db) {
  Meta meta;
  Statement rows(db, "SELECT key, value, crc FROM meta");
  while (rows.step()) {
    const std::string key = rows.text(0), value = rows.text(1);
    if (Crc().add(key.data(), key.size() + 1).add(value.data(), value.size()).value() != rows.int64(2))
      throw Error(fmt::format("CRC mismatch in meta entry '{}': the file is corrupt", key));
    meta[key] = value;
  }
  return meta;
}

std::vector<SubmapSummary> read_submaps(Database& db) {
  std::vector<SubmapSummary> submaps;
  Statement rows(db,
                 "SELECT id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc FROM submaps "
                 "ORDER BY rowid");
  while (rows.step()) {
    const int64_t id = rows.int64(0);
    const auto pose = rows.blob(1);
    SubmapSummary s;
    s.id = static_cast<int>(id);
    s.blocks = static_cast<std::size_t>(rows.int64(2));
    s.known_voxels = static_cast<std::size_t>(rows.int64(3));
    s.occupied_voxels = static_cast<std::size_t>(rows.int64(4));
    s.semantic_voxels = static_cast<std::size_t>(rows.int64(5));
    if (id != s.id || submap_crc(s, pose) != rows.int64(6))
      throw Error(fmt::format("CRC mismatch in the row of submap {}: the file is corrupt", id));
    if (pose.size() != 16 * sizeof(double))
      throw Error(fmt::format("submap {} pose has {} bytes, expected 128", id, pose.size()));
    Eigen::Matrix4d m;
    std::memcpy(m.data(), pose.data(), pose.size());
    if (!m.allFinite()) throw Error(fmt::format("submap {} has a non-finite pose", id));
    s.T_world_submap.matrix() = m;
    submaps.push_back(s);
  }
  return submaps;
}

MapFileSummary read_summary(const fs::path& path, Database& db) {
  MapFileSummary summary;
  summary.format_version = static_cast<int>(pragma_value(db, "user_version"));
  const Meta meta = read_meta(db);
  summary.params = parse_params(meta);
  summary.info = {meta_value(meta, "model_id"), meta_value(meta, "ontology"), meta_value(meta, "source")};
  summary.memory_bytes = parse_number<uint64_t>(meta, "memory_bytes");
  summary.occupancy_payload_bytes = parse_number<uint64_t>(meta, "occupancy_payload_bytes");
  summary.semantic_payload_bytes = parse_number<uint64_t>(meta, "semantic_payload_bytes");
  summary.submaps = read_submaps(db);
  for (const SubmapSummary& s : summary.submaps) {
    summary.known_voxels += s.known_voxels;
    summary.occupied_voxels += s.occupied_voxels;
    summary.semantic_voxels += s.semantic_voxels;
  }
  summary.file_bytes = fs::file_size(path);
  return summary;
}

using SubmapIndex = std::unordered_map<int64_t, Submap*>;

Submap& submap_of(const SubmapIndex& index, int64_t id, const char* table) {
  const auto it = index.find(id);
  if (it == index.end()) throw Error(fmt::format("a row of table {} refers to submap {}, which is not in the file", table, id));
  return *it->second;
}

void read_occupancy(Database& db, const SubmapIndex& index) {
  static const uint32_t kUnknownBits = std::bit_cast<uint32_t>(std::numeric_limits<float>::quiet_NaN());
  Statement rows(db, "SELECT submap, bx, by, bz, log_odds, crc FROM occupancy");
  std::array<float, OccupancyGrid::kBlockVoxels> log_odds;
  while (rows.step()) {
    const int64_t submap = rows.int64(0), bx = rows.int64(1), by = rows.int64(2), bz = rows.int64(3);
    const auto blob = rows.blob(4);
    if (Crc().add(submap).add(bx).add(by).add(bz).add(blob).value() != rows.int64(5))
      throw Error(fmt::format("CRC mismatch in occupancy block ({}, {}, {}) of submap {}: the file is corrupt", bx, by,
                              bz, submap));
    uLongf size = kBlockBytes;
    if (uncompress(reinterpret_cast<Bytef*>(log_odds.data()), &size, reinterpret_cast<const Bytef*>(blob.data()),
                   blob.size()) != Z_OK ||
        size != kBlockBytes)
      throw Error(fmt::format("occupancy block ({}, {}, {}) does not decompress to {} log-odds", bx, by, bz,
                              OccupancyGrid::kBlockVoxels));
    for (const int64_t c : {bx, by, bz})
      if (c <= -kMaxBlockCoordinate || c >= kMaxBlockCoordinate)
        throw Error(fmt::format("occupancy block coordinate {} out of range", c));
    OccupancyGrid& grid = submap_of(index, submap, "occupancy").map.occupancy();
    const VoxelKey bk(static_cast<int>(bx), static_cast<int>(by), static_cast<int>(bz));
    // A new block starts all unknown; voxel 0 is always set so that the block exists.
    for (int i = 0; i < OccupancyGrid::kBlockVoxels; ++i)
      if (i == 0 || std::bit_cast<uint32_t>(log_odds[i]) != kUnknownBits)
        grid.set_log_odds(OccupancyGrid::voxel_key(bk, i), log_odds[i]);
  }
}

void read_semantics(Database& db, const SubmapIndex& index, const SemanticParams& params) {
  const auto dim = static_cast<std::size_t>(params.dim);
  const bool fp16 = params.precision == EmbeddingPrecision::kFloat16;
  const std::size_t embedding_bytes = dim * (fp16 ? sizeof(uint16_t) : sizeof(float));
  Statement rows(db, "SELECT submap, keys, counts, embeddings, crc FROM semantics");
  std::vector<int32_t> keys;
  std::vector<uint32_t> counts;
  std::vector<uint16_t> halves(dim);
  std::vector<float> embedding(dim);
  std::unordered_map<int64_t, int64_t> chunks_read;  // per submap
  while (rows.step()) {
    const int64_t submap = rows.int64(0);
    const int64_t chunk = chunks_read[submap]++;
    const auto key_bytes = rows.blob(1), count_bytes = rows.blob(2), embedding_blob = rows.blob(3);
    if (Crc().add(submap).add(key_bytes).add(count_bytes).add(embedding_blob).value() != rows.int64(4))
      throw Error(fmt::format("CRC mismatch in semantic chunk {} of submap {}: the file is corrupt", chunk, submap));
    const std::size_t n = count_bytes.size() / sizeof(uint32_t);
    if (count_bytes.size() != n * sizeof(uint32_t) || key_bytes.size() != n * 3 * sizeof(int32_t) ||
        embedding_blob.size() != n * embedding_bytes)
      throw Error(fmt::format("semantic chunk {} of submap {} has inconsistent sizes", chunk, submap));
    SemanticLayer& layer = submap_of(index, submap, "semantics").map.semantics();
    keys.resize(3 * n);
    counts.resize(n);
    std::memcpy(keys.data(), key_bytes.data(), key_bytes.size());
    std::memcpy(counts.data(), count_bytes.data(), count_bytes.size());
    for (std::size_t j = 0; j < n; ++j) {
      if (counts[j] == 0) throw Error(fmt::format("semantic chunk {} of submap {} has a zero count", chunk, submap));
      const std::byte* src = embedding_blob.data() + j * embedding_bytes;
      if (fp16) {
        std::memcpy(halves.data(), src, embedding_bytes);
        for (std::size_t c = 0; c < dim; ++c) embedding[c] = half_to_float(halves[c]);
      } else {
        std::memcpy(embedding.data(), src, embedding_bytes);
      }
      layer.set(VoxelKey(keys[3 * j], keys[3 * j + 1], keys[3 * j + 2]), embedding.data(), counts[j]);
    }
  }
}

// Missing rows (a damaged file SQLite itself did not notice) show up as wrong counts.
void check_counts(const SemanticMap& map, const std::vector<SubmapSummary>& expected) {
  const std::vector<SubmapSummary> got = summarize_submaps(map);
  for (std::size_t i = 0; i < got.size(); ++i) {
    const SubmapSummary &g = got[i], &e = expected[i];
    if (g.blocks != e.blocks || g.known_voxels != e.known_voxels || g.occupied_voxels != e.occupied_voxels ||
        g.semantic_voxels != e.semantic_voxels)
      throw Error(fmt::format(
          "submap {} loaded with {} blocks, {} known, {} occupied, {} semantic voxels but was saved with {}, {}, {}, "
          "{}: rows are missing or duplicated",
          g.id, g.blocks, g.known_voxels, g.occupied_voxels, g.semantic_voxels, e.blocks, e.known_voxels,
          e.occupied_voxels, e.semantic_voxels));
  }
}

template <class F>
auto with_path_context(const char* action, const fs::path& path, F&& f) {
  try {
    return f();
  } catch (const Error& e) {
    throw Error(fmt::format("cannot {} {}: {}", action, path.string(), e.what()));
  } catch (const std::exception& e) {  // filesystem and allocation failures
    throw Error(fmt::format("cannot {} {}: {}", action, path.string(), e.what()));
  }
}

}  // namespace

void save_map(const fs::path& path, const SemanticMap& map) {
  with_path_context("save map", path, [&] {
    check_savable(map);
    const fs::path target = fs::absolute(path);
    TempFile temp(target);
    write_database(temp.path(), map);
    fsync_path(temp.path(), O_RDONLY);
    if (::rename(temp.path().c_str(), target.c_str()) != 0)
      throw Error(fmt::format("cannot rename {} over it: {}", temp.path().string(), errno_text()));
    temp.release();
    fsync_path(target.parent_path(), O_RDONLY | O_DIRECTORY);
    remove_stale_temp_files(target);
  });
}

MapFileSummary read_map_summary(const fs::path& path) {
  return with_path_context("read map", path, [&] {
    const auto db = open_map(path);
    return read_summary(path, *db);
  });
}

SemanticMap load_map(const fs::path& path) {
  return with_path_context("load map", path, [&] {
    const auto db = open_map(path);
    const MapFileSummary summary = read_summary(path, *db);
    SemanticMap map;
    map.params = summary.params;
    map.info = summary.info;
    map.submaps.reserve(summary.submaps.size());
    SubmapIndex index;
    for (const SubmapSummary& s : summary.submaps) {
      map.submaps.emplace_back(s.id, s.T_world_submap, map.params);
      if (!index.emplace(s.id, &map.submaps.back()).second) throw Error(fmt::format("submap id {} appears twice", s.id));
    }
    read_occupancy(*db, index);
    read_semantics(*db, index, map.params.semantic);
    check_counts(map, summary.submaps);
    return map;
  });
}

}  // namespace slamvdb
