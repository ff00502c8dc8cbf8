#pragma once
// For tests and benchmarks of a sharded fleet: servers besides the shared one
// (postgres_server.hpp), each a real PostgreSQL 15 cluster in its own temporary directory, and
// what tells which of them answered a question: their statement logs.
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::testing {

// `count` servers named `label`0, `label`1, ... for the process, stopped and removed at exit.
class PostgresServerSet {
 public:
  PostgresServerSet(int count, const std::string& label) {
    shared_postgres_server();  // first: it sweeps the directories of dead runs
    for (int i = 0; i < count; ++i) {
      dirs_.push_back(std::filesystem::temp_directory_path() /
                      ("slamvdb-postgres-" + std::to_string(::getpid()) + "-" + label + std::to_string(i)));
      std::filesystem::remove_all(dirs_.back());
      std::filesystem::create_directories(dirs_.back());
      servers_.push_back(std::make_unique<PostgresServer>(dirs_.back()));
    }
  }
  ~PostgresServerSet() {
    for (std::size_t i = 0; i < servers_.size(); ++i) {
      servers_[i].reset();
      std::error_code ignored;
      std::filesystem::remove_all(dirs_[i], ignored);
    }
  }
  PostgresServerSet(const PostgresServerSet&) = delete;
  PostgresServerSet& operator=(const PostgresServerSet&) = delete;
  PostgresServer& operator[](int i) { return *servers_.at(static_cast<std::size_t>(i)); }

 private:
  std::vector<std::filesystem::path> dirs_;
  std::vector<std::unique_ptr<PostgresServer>> servers_;
};

// Every statement logged with its database's name (`on`), or none (the default), effective when
// this returns. A benchmark turns it on only around what it observes: logging costs time.
inline void log_statements(PostgresServer& server, bool on) {
  server.psql(on ? "ALTER SYSTEM SET log_statement = 'all'" : "ALTER SYSTEM RESET log_statement");
  server.psql("ALTER SYSTEM SET log_line_prefix = '%m [%p] %d '");
  server.psql("SELECT pg_reload_conf()");
  const std::string want = on ? "all\n" : "none\n";
  for (int tries = 0; tries < 100 && server.psql("SHOW log_statement") != want; ++tries)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

// How many statements the server has logged in `database` (with log_statements on).
inline std::size_t statements_in(const PostgresServer& server, const std::string& database) {
  std::ifstream log(server.log_file());
  std::size_t n = 0;
  const std::string mark = "] " + database + " LOG:  ";
  for (std::string line; std::getline(log, line);) n += line.find(mark) != std::string::npos;
  return n;
}

}  // namespace slamvdb::testing
