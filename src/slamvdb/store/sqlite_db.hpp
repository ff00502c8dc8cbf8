#pragma once
// Thin RAII wrappers over SQLite's C API and the CRC32 every row of a map file carries. Written by
// hand because they are a few lines each and no Debian C++ SQLite wrapper is both maintained and
// smaller than this.
#include <sqlite3.h>
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "slamvdb/core/error.hpp"

namespace slamvdb::store {

class Crc {
 public:
  Crc& add(const void* data, std::size_t n) {
    value_ = crc32_z(value_, static_cast<const Bytef*>(data), n);
    return *this;
  }
  Crc& add(int64_t v) { return add(&v, sizeof v); }
  Crc& add_real(double v) { return add(&v, sizeof v); }
  Crc& add(std::span<const std::byte> bytes) { return add(bytes.data(), bytes.size()); }
  int64_t value() const { return static_cast<int64_t>(value_); }

 private:
  uLong value_ = crc32(0L, Z_NULL, 0);
};

Error sqlite_error(sqlite3* db, int rc);

class Database {
 public:
  Database(const std::filesystem::path& file, int flags) {
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
  Statement& bind_real(int i, double v) { return check(sqlite3_bind_double(stmt_, i, v)); }
  Statement& bind_null(int i) { return check(sqlite3_bind_null(stmt_, i)); }
  Statement& bind(int i, std::string_view s) {
    return check(sqlite3_bind_text64(stmt_, i, s.data(), s.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  // The bytes must stay valid until insert().
  Statement& bind(int i, std::span<const std::byte> b) {
    return check(sqlite3_bind_blob64(stmt_, i, b.data(), b.size(), SQLITE_STATIC));
  }
  int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const { return sqlite3_column_double(stmt_, col); }
  bool is_null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  void reset() { sqlite3_reset(stmt_); }
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


int64_t pragma_value(Database& db, const char* name);

template <class T>
std::span<const std::byte> bytes_of(const T& container) {
  return std::as_bytes(std::span(container));
}

}  // namespace slamvdb::store
