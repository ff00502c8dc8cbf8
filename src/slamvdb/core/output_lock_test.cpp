// One run at a time per output: a second holder fails at once naming the first one's PID and
// command; a holder that dies, even by SIGKILL, blocks nobody.
#include "slamvdb/core/output_lock.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

TEST(OutputLock, ASecondHolderFailsNamingTheFirst) {
  testing::TempDir dir;
  const fs::path map = dir.path / "m.svdb";
  {
    OutputLock first(map);
    EXPECT_EQ(first.lock_file(), dir.path / ".m.svdb.lock");
    const std::string e = error_of([&] { OutputLock second(map); });
    EXPECT_NE(e.find("is being written by another slamvdb run"), std::string::npos) << e;
    EXPECT_NE(e.find("PID " + std::to_string(::getpid())), std::string::npos) << e;
    EXPECT_NE(e.find(map.string()), std::string::npos) << e;
    // Another name of the same file is the same output.
    fs::create_symlink(map, dir.path / "alias.svdb");
    EXPECT_FALSE(error_of([&] { OutputLock again(dir.path / "alias.svdb"); }).empty());
  }
  EXPECT_FALSE(fs::exists(dir.path / ".m.svdb.lock"));  // released and removed
  OutputLock after(map);
}

TEST(OutputLock, AKilledHolderBlocksNobody) {
  testing::TempDir dir;
  const fs::path map = dir.path / "m.svdb";
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    try {
      OutputLock held(map);
      const char c = 1;
      if (::write(ready[1], &c, 1) != 1) ::_exit(2);
      ::pause();
    } catch (...) {
      ::_exit(1);
    }
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  const std::string e = error_of([&] { OutputLock second(map); });
  EXPECT_NE(e.find("PID " + std::to_string(child)), std::string::npos) << e;
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  EXPECT_TRUE(fs::exists(dir.path / ".m.svdb.lock"));  // left behind by the killed holder
  EXPECT_EQ(error_of([&] { OutputLock taken_over(map); }), "");
  ::close(ready[0]);
  ::close(ready[1]);
}

}  // namespace
}  // namespace slamvdb
