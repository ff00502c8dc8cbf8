#include "slamvdb/core/output_file.hpp"

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <stdexcept>

#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

std::string slurp(const fs::path& p) { return read_regular_file(p, "test file"); }

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

// A small tmpfs (a full disk after `bytes`), or a read-only one; needs CAP_SYS_ADMIN, so tests
// using it are skipped where mounting is not allowed.
struct ScopedTmpfs {
  fs::path path;
  bool mounted = false;
  ScopedTmpfs(const fs::path& where, const std::string& options) : path(where) {
    fs::create_directories(path);
    mounted = ::mount("tmpfs", path.c_str(), "tmpfs", 0, options.c_str()) == 0;
  }
  void remount_read_only() {
    ASSERT_EQ(::mount("tmpfs", path.c_str(), "tmpfs", MS_REMOUNT | MS_RDONLY, nullptr), 0);
  }
  ~ScopedTmpfs() {
    if (mounted) ::umount2(path.c_str(), MNT_DETACH);
  }
};

TEST(OutputFile, WritesAndLeavesNoTemporary) {
  testing::TempDir dir;
  const fs::path target = dir.path / "out.bin";
  write_output_file(target, "first");
  EXPECT_EQ(slurp(target), "first");
  OutputFile f(target);
  f.write("sec");
  f.write(std::string_view("ond"));
  EXPECT_TRUE(is_output_temp_file(f.temp_path()));
  EXPECT_EQ(f.temp_path().parent_path(), target.parent_path());
  EXPECT_EQ(slurp(target), "first");  // untouched until commit
  f.commit();
  EXPECT_EQ(slurp(target), "second");
  EXPECT_EQ(entries(dir.path), 1u);
}

TEST(OutputFile, AnAbandonedWriteKeepsThePreviousFile) {
  testing::TempDir dir;
  const fs::path target = dir.path / "map.ply";
  write_output_file(target, "complete");
  {
    OutputFile f(target, {.sync = false});
    f.write("half of a new fi");
  }  // an exception unwinding through the writer does this
  EXPECT_EQ(slurp(target), "complete");
  EXPECT_EQ(entries(dir.path), 1u);
  const std::string e = error_of([&] {
    write_output_file_with(target, [](const fs::path& temp) {
      std::ofstream(temp) << "partial";
      throw Error("encoder failed");
    });
  });
  EXPECT_EQ(e, "encoder failed");
  EXPECT_EQ(slurp(target), "complete");
  EXPECT_EQ(entries(dir.path), 1u);
  write_output_file_with(target, [](const fs::path& temp) { std::ofstream(temp) << "by name"; });
  EXPECT_EQ(slurp(target), "by name");
}

TEST(OutputFile, MissingDirectoryIsAnErrorNamingTheTarget) {
  testing::TempDir dir;
  const std::string e = error_of([&] { write_output_file(dir.path / "no" / "such.npy", "x"); });
  EXPECT_NE(e.find("such.npy"), std::string::npos) << e;
  EXPECT_NE(e.find("does not exist"), std::string::npos) << e;
  EXPECT_FALSE(error_of([&] { write_output_file(dir.path, "x"); }).empty());  // a directory, not a file
}

TEST(OutputFile, FullDiskLeavesThePreviousFileAndNoTemporary) {
  testing::TempDir dir;
  ScopedTmpfs disk(dir.path / "small", "size=64k");
  if (!disk.mounted) GTEST_SKIP() << "cannot mount a tmpfs here (needs CAP_SYS_ADMIN)";
  const fs::path target = disk.path / "features.npy";
  write_output_file(target, "old content");
  const std::string e = error_of([&] { write_output_file(target, std::string(1 << 20, 'x')); });
  EXPECT_NE(e.find("No space left on device"), std::string::npos) << e;
  EXPECT_NE(e.find("features.npy"), std::string::npos) << e;
  EXPECT_EQ(slurp(target), "old content");
  EXPECT_EQ(entries(disk.path), 1u);
}

TEST(OutputFile, ReadOnlyTargetIsAnError) {
  testing::TempDir dir;
  ScopedTmpfs disk(dir.path / "ro", "size=64k");
  if (!disk.mounted) GTEST_SKIP() << "cannot mount a tmpfs here (needs CAP_SYS_ADMIN)";
  write_output_file(disk.path / "a.png", "old");
  disk.remount_read_only();
  const std::string e = error_of([&] { write_output_file(disk.path / "a.png", "new"); });
  EXPECT_NE(e.find("Read-only file system"), std::string::npos) << e;
  EXPECT_EQ(slurp(disk.path / "a.png"), "old");
}

TEST(OutputFile, StaleTemporariesOfDeadWritersAreRemoved) {
  testing::TempDir dir;
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);  // reaped: its PID now names no process
  const fs::path stale = dir.path / (".map.svdb.tmp-" + std::to_string(child) + "-0");
  const fs::path ours = dir.path / (".map.svdb.tmp-" + std::to_string(::getpid()) + "-3");
  const fs::path other = dir.path / ".hidden.tmp-notapid";
  for (const auto& p : {stale, ours, other}) std::ofstream(p) << "x";
  EXPECT_TRUE(is_output_temp_file(stale));
  EXPECT_FALSE(is_output_temp_file(other));
  EXPECT_FALSE(is_output_temp_file(dir.path / "map.svdb"));
  EXPECT_EQ(remove_stale_temp_files(dir.path), 1u);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(ours));
  EXPECT_TRUE(fs::exists(other));
}

}  // namespace
}  // namespace slamvdb
