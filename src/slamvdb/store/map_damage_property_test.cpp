// Property: random damage to a valid map file (truncation, bit flips, overwritten byte ranges,
// rows deleted or duplicated with their checksums intact) never crashes the loader and never gives
// a map with a non-finite value: a damaged file is refused with an Error, or loads consistently.
// SLAMVDB_MAP_DAMAGE_CASES sets the number of cases (default 120; e.g. 5000 for a long run).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdlib>
#include <random>

#include "slamvdb/testing/map_checks.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using namespace slamvdb::testing;

void sql(const fs::path& file, const std::string& statement) {
  sqlite3* db = nullptr;
  if (sqlite3_open(file.c_str(), &db) == SQLITE_OK) sqlite3_exec(db, statement.c_str(), nullptr, nullptr, nullptr);
  sqlite3_close(db);  // errors are fine: the damage may already have broken the file
}

TEST_F(MapStoreTest, RandomDamageNeverCrashesOrLoadsNonFiniteValues) {
  const fs::path good = dir_ / "good.svdb", damaged = dir_ / "damaged.svdb";
  save_map(good, make_map(EmbeddingPrecision::kFloat16, 16, 7));
  const std::string bytes = read_bytes(good);
  const char* env = std::getenv("SLAMVDB_MAP_DAMAGE_CASES");
  const int cases = env ? std::atoi(env) : 120;
  std::mt19937_64 rng(20261124);
  std::size_t loaded = 0, refused = 0;
  const char* kTables[] = {"meta", "submaps", "occupancy", "semantics"};
  for (int c = 0; c < cases; ++c) {
    std::string b = bytes;
    const int kind = static_cast<int>(rng() % 5);
    if (kind == 0) {  // truncated
      b.resize(rng() % b.size());
    } else if (kind == 1) {  // bit flips
      for (int i = 0, n = 1 + static_cast<int>(rng() % 16); i < n; ++i) b[rng() % b.size()] ^= static_cast<char>(1 << (rng() % 8));
    } else if (kind == 2) {  // a byte range overwritten with noise
      const std::size_t at = rng() % b.size(), n = std::min<std::size_t>(b.size() - at, 1 + rng() % 4096);
      for (std::size_t i = 0; i < n; ++i) b[at + i] = static_cast<char>(rng());
    }
    write_bytes(damaged, b);
    const std::string table = kTables[rng() % 4];
    if (kind == 3) sql(damaged, "DELETE FROM " + table + " WHERE rowid IN (SELECT rowid FROM " + table +
                                    " ORDER BY random() LIMIT 1)");
    if (kind == 4) sql(damaged, "INSERT INTO " + table + " SELECT * FROM " + table + " ORDER BY random() LIMIT 1");
    try {
      const SemanticMap map = load_map(damaged);
      const std::string bad = first_non_finite_value(map);
      EXPECT_TRUE(bad.empty()) << "case " << c << " (kind " << kind << "): " << bad;
      std::size_t cells = 0;
      map.read_index([&](const GlobalIndex& index) { cells = index.size(); });
      EXPECT_EQ(cells, map.num_index_cells());
      ++loaded;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(damaged.string()), std::string::npos) << e.what();  // names the file
      ++refused;
    }
  }
  std::cout << cases << " damaged map files: " << refused << " refused with an error, " << loaded
            << " loaded with finite values\n";
  EXPECT_GT(refused, 0u);
}

}  // namespace
}  // namespace slamvdb
