#include "slamvdb/core/regular_file.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using testing::error_of;

TEST(RegularFile, ReadsRegularFilesWhole) {
  testing::TempDir dir;
  const auto file = dir.path / "a.txt";
  std::ofstream(file) << "hello\n";
  EXPECT_EQ(read_regular_file(file, "text file"), "hello\n");
  std::ofstream(dir.path / "empty.txt");
  EXPECT_EQ(read_regular_file(dir.path / "empty.txt", "text file"), "");
  std::filesystem::create_symlink(file, dir.path / "link.txt");
  EXPECT_EQ(read_regular_file(dir.path / "link.txt", "text file"), "hello\n");  // symlinks are followed
}

TEST(RegularFile, NamesWhatThePathIsInsteadOfBlocking) {
  testing::TempDir dir;
  const auto fifo = dir.path / "times.txt";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Without O_NONBLOCK this open would wait forever for a writer.
  const std::string e = error_of([&] { read_regular_file(fifo, "time stamp file"); });
  EXPECT_NE(e.find("time stamp file"), std::string::npos) << e;
  EXPECT_NE(e.find("times.txt"), std::string::npos) << e;
  EXPECT_NE(e.find("FIFO"), std::string::npos) << e;
  EXPECT_NE(error_of([&] { require_regular_file(fifo, "poses"); }).find("FIFO"), std::string::npos);
  EXPECT_NE(error_of([&] { read_regular_file(dir.path, "poses"); }).find("is a directory"), std::string::npos);
  EXPECT_NE(error_of([&] { read_regular_file("/dev/zero", "scan file"); }).find("character device"),
            std::string::npos);
  EXPECT_NE(error_of([&] { read_regular_file(dir.path / "missing", "poses"); }).find("does not exist"),
            std::string::npos);
}

TEST(RegularFile, RefusesFilesAboveTheBound) {
  testing::TempDir dir;
  std::ofstream(dir.path / "big.txt") << std::string(100, 'x');
  const std::string e = error_of([&] { read_regular_file(dir.path / "big.txt", "manifest", 10); });
  EXPECT_NE(e.find("100 bytes"), std::string::npos) << e;
  RegularFile f(dir.path / "big.txt", "manifest");
  char buffer[200];
  EXPECT_NE(error_of([&] { f.read_exact(buffer, sizeof buffer); }).find("ended after 100 of 200 bytes"),
            std::string::npos);
}

}  // namespace
}  // namespace slamvdb
