#pragma once
// For tests only: a real PostgreSQL 15 server in a temporary directory (initdb + pg_ctl), reached
// through a Unix socket in that directory (no TCP port, so parallel tests never collide), with
// trust authentication for its superuser `postgres`. PostgreSQL refuses to run as root and CI runs
// as root, so there the server runs as the unprivileged `postgres` account Debian's package
// creates (runuser); as any other user it runs as that user.
// A test process that aborts (a sanitizer, a crash, a kill) runs no destructor: a watchdog started
// with each server stops it when its owner process is gone, and shared_postgres_server() sweeps
// the directories of dead owners at start (sweep_stale_postgres_dirs), so no server outlives a run.
#include <gtest/gtest.h>
#include <pwd.h>
#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <string_view>
#include <thread>
#include <filesystem>
#include <memory>
#include <sstream>
#include <vector>
#include <stdexcept>
#include <string>

#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

class PostgresServer {
 public:
  static constexpr const char* kBinDir = "/usr/lib/postgresql/15/bin";

  // Creates the cluster in `dir`/pg (dir must exist) and starts it. With `watchdog`, a detached
  // shell loop polls this process and, once it is gone, stops the server (immediate mode) and
  // removes `dir` and the socket directory; it ends by itself when `dir`/pg is removed.
  explicit PostgresServer(const std::filesystem::path& dir, bool watchdog = true) : root_(dir / "pg") {
    std::filesystem::create_directories(root_);
    // The socket's own short directory: a Unix socket path holds at most 107 bytes.
    std::string socket_template = (std::filesystem::temp_directory_path() / "svdb-pg-XXXXXX").string();
    if (!::mkdtemp(socket_template.data())) throw std::runtime_error("cannot create a socket directory");
    socket_dir_ = socket_template;
    if (::geteuid() == 0) {
      const passwd* account = ::getpwnam("postgres");
      if (!account) throw std::runtime_error("running as root and there is no `postgres` account to run the server as");
      for (const std::filesystem::path& owned : {root_, socket_dir_})
        if (::chown(owned.c_str(), account->pw_uid, account->pw_gid) != 0)
          throw std::runtime_error("cannot hand " + owned.string() + " to the postgres account");
      as_user_ = "runuser -u postgres -- ";
    }
    run("initdb -D " + quote_path(data()) + " -A trust -U postgres -E UTF8 --no-sync --no-instructions", 120);
    if (watchdog) start_watchdog(dir);
    start();
  }
  ~PostgresServer() {
    if (running_) run_command(as_user_ + bin("pg_ctl") + " -D " + quote_path(data()) + " -m immediate -w stop", 60);
    std::error_code ignored;
    std::filesystem::remove_all(socket_dir_, ignored);
  }
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  void start() {
    // fsync off: a test server's data need not survive a power cut, only a server kill.
    const std::filesystem::path log = log_file();
    const CommandResult r = run_command(
        as_user_ + bin("pg_ctl") + " -D " + quote_path(data()) + " -l " + quote_path(log) + " -w -t 60 -o " +
            shell_quote("-k " + socket_dir_.string() + " -c listen_addresses='' -p 5432 -c fsync=off -c max_connections=40") +
            " start",
        90);
    if (r.exit_code != 0) {
      std::ifstream in(log);
      const std::string server_log((std::istreambuf_iterator<char>(in)), {});
      throw std::runtime_error("pg_ctl start failed: " + r.output + "\nserver log:\n" + server_log);
    }
    running_ = true;
  }
  // A fast shutdown (clients disconnected, consistent on disk).
  void stop() {
    run("pg_ctl -D " + quote_path(data()) + " -m fast -w stop", 60);
    running_ = false;
  }
  // The server's processes killed without warning, as a crash or a pulled plug leaves them: the
  // postmaster is frozen first (so it restarts no backend), its children killed, then itself.
  void kill_hard() {
    std::ifstream pid_file(data() / "postmaster.pid");
    long pid = 0;
    if (!(pid_file >> pid) || pid <= 0) throw std::runtime_error("no postmaster.pid in " + data().string());
    ::kill(static_cast<pid_t>(pid), SIGSTOP);
    std::vector<long> doomed{pid};
    std::istringstream children(run_command("pgrep -P " + std::to_string(pid)).output);
    for (long child = 0; children >> child;) doomed.push_back(child);
    for (const long p : doomed) ::kill(static_cast<pid_t>(p), SIGKILL);
    const auto alive = [](long p) {  // a zombie (nobody reaps a daemon here) counts as gone
      std::ifstream stat("/proc/" + std::to_string(p) + "/stat");
      std::string pid_text, name, state;
      return stat >> pid_text >> name >> state && state != "Z";
    };
    for (const long p : doomed)
      for (int i = 0; i < 400 && alive(p); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    // Where nobody reaps daemons (a container whose PID 1 does not), the dead postmaster stays a
    // zombie, which PostgreSQL's lock-file checks take for a running server: its lock files go,
    // as an administrator would remove them after making sure the process is dead.
    std::filesystem::remove(data() / "postmaster.pid");
    std::filesystem::remove(socket_dir_ / ".s.PGSQL.5432.lock");
    running_ = false;
  }

  // A libpq connection URL for `database` on this server.
  std::string url(const std::string& database = "postgres") const {
    return "postgresql:///" + database + "?host=" + socket_dir_.string() + "&port=5432&user=postgres";
  }
  // Runs `sql` through psql (an independent client, not ours) as the superuser; throws on failure.
  std::string psql(const std::string& sql, const std::string& database = "postgres") const {
    const CommandResult r = run_command(bin("psql") + " -X -q -A -t -v ON_ERROR_STOP=1 -d " + shell_quote(url(database)) +
                                        " -c " + shell_quote(sql), 60);
    if (r.exit_code != 0) throw std::runtime_error("psql failed: " + r.output);
    return r.output;
  }
  std::filesystem::path data() const { return root_ / "data"; }
  // The server's log (pg_ctl -l): what a test reads to see which statements a server ran.
  std::filesystem::path log_file() const { return root_ / "server.log"; }

 private:
  static std::string bin(const std::string& name) { return std::string(kBinDir) + "/" + name; }
  // setsid: the loop is in its own session, so a signal to the test's process group spares it;
  // std::system returns at once (the loop runs in the background, its output to /dev/null).
  void start_watchdog(const std::filesystem::path& dir) const {
    const std::string loop = "while kill -0 " + std::to_string(::getpid()) + " 2>/dev/null && [ -d " + quote_path(root_) +
                             " ]; do sleep 0.2; done; if [ -d " + quote_path(root_) + " ]; then " + as_user_ +
                             bin("pg_ctl") + " -D " + quote_path(data()) + " -m immediate -w stop; rm -rf " +
                             quote_path(dir) + " " + quote_path(socket_dir_) + "; fi";
    const std::string command = "setsid /bin/sh -c " + shell_quote(loop) + " </dev/null >/dev/null 2>&1 &";
    if (std::system(command.c_str()) != 0) throw std::runtime_error("cannot start the server's watchdog");
  }
  void run(const std::string& command, double timeout) const {
    const CommandResult r = run_command(as_user_ + bin(command), timeout);
    if (r.exit_code != 0) throw std::runtime_error(command + " failed: " + r.output);
  }

  std::filesystem::path root_, socket_dir_;
  std::string as_user_;
  bool running_ = false;
};

// The directories `parent`/slamvdb-postgres-PID whose process PID is gone (a test process that
// aborted before its watchdog existed, or whose watchdog was killed too): their server is stopped
// (immediate mode; its socket directory is line 5 of postmaster.pid) and the directories removed.
// Returns how many were swept.
inline int sweep_stale_postgres_dirs(const std::filesystem::path& parent = std::filesystem::temp_directory_path()) {
  constexpr std::string_view kPrefix = "slamvdb-postgres-";
  int swept = 0;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(parent, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(kPrefix, 0) != 0 || name.size() == kPrefix.size()) continue;
    const std::string pid_text = name.substr(kPrefix.size());
    if (pid_text.find_first_not_of("0123456789") != std::string::npos) continue;
    const long owner = std::stol(pid_text);
    if (owner <= 0 || ::kill(static_cast<pid_t>(owner), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours)
    const std::filesystem::path data = entry.path() / "pg" / "data";
    std::ifstream pid_file(data / "postmaster.pid");
    std::string line, socket_dir;
    for (int i = 0; i < 5 && std::getline(pid_file, line); ++i) socket_dir = line;
    if (std::filesystem::exists(data / "postmaster.pid"))
      run_command(std::string(::geteuid() == 0 ? "runuser -u postgres -- " : "") + PostgresServer::kBinDir +
                      "/pg_ctl -D " + quote_path(data) + " -m immediate -w stop",
                  60);
    std::error_code ignored;
    if (socket_dir.rfind((std::filesystem::temp_directory_path() / "svdb-pg-").string(), 0) == 0)
      std::filesystem::remove_all(socket_dir, ignored);
    std::filesystem::remove_all(entry.path(), ignored);
    ++swept;
  }
  return swept;
}

// One server for the whole test process: started on first use (about 1 s), stopped and removed
// at exit. Tests keep apart by each using its own database (fresh_test_database).
inline PostgresServer& shared_postgres_server() {
  struct Owner {
    std::filesystem::path dir = std::filesystem::temp_directory_path() / ("slamvdb-postgres-" + std::to_string(::getpid()));
    std::unique_ptr<PostgresServer> server;
    Owner() {
      sweep_stale_postgres_dirs();
      std::filesystem::remove_all(dir);
      std::filesystem::create_directories(dir);
      server = std::make_unique<PostgresServer>(dir);
    }
    ~Owner() {
      server.reset();
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  };
  static Owner owner;
  return *owner.server;
}

// A new, empty database named after the running test (and `suffix`); returns its name.
inline std::string fresh_test_database(PostgresServer& server, const std::string& suffix = "") {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = "t";
  for (const char c : std::string(info->test_suite_name()) + "_" + info->name() + suffix)
    name += std::isalnum(static_cast<unsigned char>(c)) ? static_cast<char>(std::tolower(static_cast<unsigned char>(c))) : '_';
  if (name.size() > 60) name = name.substr(0, 44) + "_" + std::to_string(std::hash<std::string>{}(name) % 1000000007);
  server.psql("DROP DATABASE IF EXISTS " + name);
  server.psql("CREATE DATABASE " + name);
  return name;
}

// psql's answer without its final newline.
inline std::string psql_value(PostgresServer& server, const std::string& sql, const std::string& database) {
  std::string out = server.psql(sql, database);
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

}  // namespace slamvdb::testing
