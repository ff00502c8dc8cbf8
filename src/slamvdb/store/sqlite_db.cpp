#include "slamvdb/store/sqlite_db.hpp"

#include <fmt/format.h>

namespace slamvdb::store {

Error sqlite_error(sqlite3* db, int rc) {
  const std::string msg = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_NOTADB: return Error("not an SQLite database, so not a slamvdb map (SQLite: " + msg + ")");
    case SQLITE_CORRUPT: return Error("the file is damaged or truncated (SQLite: " + msg + ")");
    default: return Error("SQLite: " + msg);
  }
}

int64_t pragma_value(Database& db, const char* name) {
  Statement s(db, fmt::format("PRAGMA {}", name));
  if (!s.step()) throw Error(fmt::format("PRAGMA {} returned nothing", name));
  return s.int64(0);
}

}  // namespace slamvdb::store
