#pragma once
// For tests only: a real PostgreSQL 15 server in a temporary directory (initdb + pg_ctl), reached
// through a Unix socket in that directory (no TCP port, so parallel tests never collide), with
// trust authentication for its superuser `postgres`. PostgreSQL refuses to run as root and CI runs
// as root, so there the server runs as the unprivileged `postgres` account Debian's package
// creates (runuser); as any other user it runs as that user.
#include <pwd.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

class PostgresServer {
 public:
  static constexpr const char* kBinDir = "/usr/lib/postgresql/15/bin";

  // Creates the cluster in `dir`/pg (dir must exist) and starts it.
  explicit PostgresServer(const std::filesystem::path& dir) : root_(dir / "pg") {
    std::filesystem::create_directories(root_);
    if (::geteuid() == 0) {
      const passwd* account = ::getpwnam("postgres");
      if (!account) throw std::runtime_error("running as root and there is no `postgres` account to run the server as");
      if (::chown(root_.c_str(), account->pw_uid, account->pw_gid) != 0)
        throw std::runtime_error("cannot hand " + root_.string() + " to the postgres account");
      as_user_ = "runuser -u postgres -- ";
    }
    run("initdb -D " + quote_path(data()) + " -A trust -U postgres -E UTF8 --no-sync --no-instructions", 120);
    start();
  }
  ~PostgresServer() {
    if (running_) run_command(as_user_ + bin("pg_ctl") + " -D " + quote_path(data()) + " -m immediate -w stop", 60);
  }
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  void start() {
    // fsync off: a test server's data need not survive a power cut, only a server kill.
    run("pg_ctl -D " + quote_path(data()) + " -l " + quote_path(root_ / "server.log") + " -w -t 60 -o " +
            shell_quote("-k " + root_.string() + " -c listen_addresses='' -p 5432 -c fsync=off -c max_connections=40") + " start",
        90);
    running_ = true;
  }
  // A fast shutdown (clients disconnected, consistent on disk).
  void stop() {
    run("pg_ctl -D " + quote_path(data()) + " -m fast -w stop", 60);
    running_ = false;
  }
  // The server's processes killed without warning: what a crash or a pulled plug leaves behind.
  void kill_hard() {
    run_command(as_user_ + "/bin/sh -c " + shell_quote("kill -9 $(head -1 " + (data() / "postmaster.pid").string() + ")"));
    for (int i = 0; i < 200 && run_command("pgrep -f " + shell_quote("postgres -D " + data().string())).exit_code == 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    running_ = false;
  }

  // A libpq connection URL for `database` on this server.
  std::string url(const std::string& database = "postgres") const {
    return "postgresql:///" + database + "?host=" + root_.string() + "&port=5432&user=postgres";
  }
  // Runs `sql` through psql (an independent client, not ours) as the superuser; throws on failure.
  std::string psql(const std::string& sql, const std::string& database = "postgres") const {
    const CommandResult r = run_command(bin("psql") + " -X -q -A -t -v ON_ERROR_STOP=1 -d " + shell_quote(url(database)) +
                                        " -c " + shell_quote(sql), 60);
    if (r.exit_code != 0) throw std::runtime_error("psql failed: " + r.output);
    return r.output;
  }
  std::filesystem::path data() const { return root_ / "data"; }

 private:
  static std::string bin(const std::string& name) { return std::string(kBinDir) + "/" + name; }
  void run(const std::string& command, double timeout) const {
    const CommandResult r = run_command(as_user_ + bin(command), timeout);
    if (r.exit_code != 0) throw std::runtime_error(command + " failed: " + r.output);
  }

  std::filesystem::path root_;
  std::string as_user_;
  bool running_ = false;
};

}  // namespace slamvdb::testing
