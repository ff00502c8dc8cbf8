// The test harness's own guarantee (testing/postgres_server.hpp): a test process that dies without
// running its destructors (SIGKILL here; an ASan abort or a crash alike) leaves no PostgreSQL
// server behind, through the server's watchdog or, without one, the sweep of stale directories.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <functional>
#include <fstream>
#include <thread>

#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

// A process that exists and is not a zombie (nobody may reap a daemon in a container).
bool harness_process_alive(long pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string pid_text, name, state;
  return stat >> pid_text >> name >> state && state != "Z";
}

bool harness_wait_until(const std::function<bool()>& done, double seconds) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

// Forks a child that starts a server in `dir` (with or without its watchdog), waits for it to be
// up, SIGKILLs the child (no destructor runs) and returns the server's postmaster pid.
long start_server_in_killed_child(const std::filesystem::path& dir, bool watchdog) {
  const std::filesystem::path ready = dir.parent_path() / (dir.filename().string() + ".ready");
  std::filesystem::create_directories(dir);
  const pid_t child = ::fork();
  if (child == 0) {
    try {
      slamvdb::testing::PostgresServer server(dir, watchdog);
      std::ofstream(ready) << "up\n";
      while (true) ::pause();
    } catch (...) {
      ::_exit(3);
    }
  }
  EXPECT_GT(child, 0);
  const bool up = harness_wait_until([&] { return std::filesystem::exists(ready); }, 120);
  long postmaster = 0;
  std::ifstream(dir / "pg" / "data" / "postmaster.pid") >> postmaster;
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  std::filesystem::remove(ready);
  EXPECT_TRUE(up) << "the child's server did not start";
  EXPECT_GT(postmaster, 0);
  return postmaster;
}

TEST(PostgresHarness, AServerOfAKilledTestProcessIsStoppedByItsWatchdog) {
  slamvdb::testing::TempDir tmp;
  const std::filesystem::path dir = tmp.path / "owned";
  const long postmaster = start_server_in_killed_child(dir, true);
  ASSERT_TRUE(harness_process_alive(postmaster));  // the child is gone, its server still up for now
  EXPECT_TRUE(harness_wait_until([&] { return !harness_process_alive(postmaster); }, 10)) << "server " << postmaster << " still runs";
  EXPECT_TRUE(harness_wait_until([&] { return !std::filesystem::exists(dir); }, 10)) << dir << " was not removed";
}

TEST(PostgresHarness, StaleDirectoriesOfDeadOwnersAreSweptAndTheirServersStopped) {
  slamvdb::testing::TempDir tmp;
  // The layout shared_postgres_server() uses: parent/slamvdb-postgres-PID, PID the owner's. The
  // child's pid is only known after the fork: a directory named after it is made by renaming.
  const std::filesystem::path staging = tmp.path / "staging";
  const long postmaster = start_server_in_killed_child(staging, false);
  ASSERT_TRUE(harness_process_alive(postmaster));
  // A live owner's directory (ours) stays; the dead owner's (pid 2^22+1 > pid_max: never alive) goes.
  const std::filesystem::path live = tmp.path / ("slamvdb-postgres-" + std::to_string(::getpid()));
  std::filesystem::create_directories(live);
  const std::filesystem::path dead = tmp.path / "slamvdb-postgres-4194305";
  std::filesystem::rename(staging, dead);
  // pg_ctl finds the server by its data directory's postmaster.pid, which moved with it.
  EXPECT_TRUE(harness_process_alive(postmaster)) << "without a watchdog nothing stops the server";
  EXPECT_EQ(slamvdb::testing::sweep_stale_postgres_dirs(tmp.path), 1);
  EXPECT_TRUE(harness_wait_until([&] { return !harness_process_alive(postmaster); }, 10)) << "server " << postmaster << " still runs";
  EXPECT_FALSE(std::filesystem::exists(dead));
  EXPECT_TRUE(std::filesystem::exists(live));
}

}  // namespace
}  // namespace slamvdb::fleet
