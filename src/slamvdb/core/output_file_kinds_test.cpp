// The one writer by what is at the output path: character devices and FIFOs are written through
// and stay what they are (a full device is an error naming file and reason), symbolic links are
// followed and stay links, directories, block devices and sockets are refused.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <functional>
#include <future>
#include <iterator>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

// mknod needs CAP_MKNOD (root in CI); elsewhere the test is skipped.
#define MAKE_NODE_OR_SKIP(path, mode, major, minor)                                                 \
  if (::mknod((path).c_str(), (mode) | 0666, makedev(major, minor)) != 0)                          \
  GTEST_SKIP() << "cannot create device nodes here (mknod: " << std::strerror(errno) << "; needs root)"

bool is_char_device(const fs::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

// Reads a FIFO to its end on another thread.
std::future<std::string> read_fifo(const fs::path& fifo) {
  return std::async(std::launch::async, [fifo] {
    std::ifstream in(fifo, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  });
}

TEST(OutputFileKinds, NullDeviceIsWrittenThroughAndStaysADevice) {
  testing::TempDir dir;
  const fs::path null = dir.path / "null";
  MAKE_NODE_OR_SKIP(null, S_IFCHR, 1, 3);
  EXPECT_EQ(resolve_output(null).kind, OutputKind::kStream);
  write_output_file(null, std::string(1 << 20, 'x'));
  write_output_file_with(null, [](const fs::path& file) { std::ofstream(file) << "by name"; });
  EXPECT_TRUE(is_char_device(null));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path), fs::directory_iterator()), 1);
}

TEST(OutputFileKinds, FullDeviceIsAnErrorNamingTheFileAndTheReason) {
  testing::TempDir dir;
  const fs::path full = dir.path / "full.csv";
  MAKE_NODE_OR_SKIP(full, S_IFCHR, 1, 7);
  for (const auto& write : std::vector<std::function<void()>>{
           [&] { write_output_file(full, "x,y,z\n"); },
           [&] { write_output_file_with(full, [](const fs::path& file) { std::ofstream(file) << "by name"; }); }}) {
    const std::string e = error_of(write);
    EXPECT_NE(e.find("No space left on device"), std::string::npos) << e;
    EXPECT_NE(e.find(full.string()), std::string::npos) << e;
    EXPECT_TRUE(is_char_device(full));
  }
}

TEST(OutputFileKinds, FifoIsWrittenThroughWhileSomeoneReads) {
  testing::TempDir dir;
  const fs::path fifo = dir.path / "pipe.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string bytes(3 << 20, 'p');  // more than a pipe buffer
  auto got = read_fifo(fifo);
  write_output_file(fifo, bytes);
  EXPECT_EQ(got.get(), bytes);
  auto by_name = read_fifo(fifo);  // a writer that needs a file name: copied through at commit
  write_output_file_with(fifo, [](const fs::path& file) { std::ofstream(file) << "sqlite or opencv"; });
  EXPECT_EQ(by_name.get(), "sqlite or opencv");
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

TEST(OutputFileKinds, AReaderThatGoesAwayIsABrokenPipeErrorNotASignal) {
  testing::TempDir dir;
  const fs::path fifo = dir.path / "pipe.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto reader = std::async(std::launch::async, [&] {
    const int fd = ::open(fifo.c_str(), O_RDONLY);
    char c = 0;
    const ssize_t n = ::read(fd, &c, 1);  // one byte, then it hangs up
    ::close(fd);
    return n;
  });
  const std::string e = error_of([&] { write_output_file(fifo, std::string(8 << 20, 'x')); });
  EXPECT_EQ(reader.get(), 1);
  EXPECT_NE(e.find("Broken pipe"), std::string::npos) << e;
  EXPECT_NE(e.find(fifo.string()), std::string::npos) << e;
}

TEST(OutputFileKinds, OpenDescriptorsAreWrittenToNotReopened) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const fs::path alias = "/dev/fd/" + std::to_string(fds[1]);
  const OutputTarget target = resolve_output(alias);
  EXPECT_EQ(target.kind, OutputKind::kStream);
  EXPECT_EQ(target.descriptor, fds[1]);
  EXPECT_EQ(resolve_output("/dev/stdout").descriptor, 1);
  EXPECT_EQ(resolve_output("/proc/self/fd/2").descriptor, 2);
  write_output_file(alias, "through the pipe");
  ::close(fds[1]);  // the writer closed its own duplicate; this is the last write end
  char buffer[64] = {};
  EXPECT_EQ(::read(fds[0], buffer, sizeof buffer), 16);
  EXPECT_EQ(std::string(buffer), "through the pipe");
  ::close(fds[0]);
}

TEST(OutputFileKinds, SymbolicLinksAreFollowedAndStayLinks) {
  testing::TempDir dir;
  fs::create_directory(dir.path / "real");
  const fs::path file = dir.path / "real" / "poses.txt";
  std::ofstream(file) << "old";
  fs::permissions(file, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  const fs::path link = dir.path / "latest.txt", chain = dir.path / "chain.txt";
  fs::create_symlink("real/poses.txt", link);  // relative to the link's folder
  fs::create_symlink(link, chain);
  EXPECT_EQ(resolve_output(chain).resolved, dir.path / "real" / "poses.txt");
  write_output_file(chain, "new");
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_TRUE(fs::is_symlink(chain));
  EXPECT_EQ(read_regular_file(file, "test"), "new");
  // The replacement keeps the permissions of the file it replaced.
  EXPECT_EQ(fs::status(file).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  // A dangling link: its target is created.
  const fs::path dangling = dir.path / "next.txt";
  fs::create_symlink("real/created.txt", dangling);
  write_output_file(dangling, "created");
  EXPECT_TRUE(fs::is_symlink(dangling));
  EXPECT_EQ(read_regular_file(dir.path / "real" / "created.txt", "test"), "created");
  // A loop is refused.
  fs::create_symlink(dir.path / "loop_b", dir.path / "loop_a");
  fs::create_symlink(dir.path / "loop_a", dir.path / "loop_b");
  EXPECT_NE(error_of([&] { resolve_output(dir.path / "loop_a"); }).find("too many levels"), std::string::npos);
}

TEST(OutputFileKinds, DirectoriesBlockDevicesAndSocketsAreRefusedUntouched) {
  testing::TempDir dir;
  std::string e = error_of([&] { write_output_file(dir.path, "x"); });
  EXPECT_NE(e.find("a directory"), std::string::npos) << e;
  fs::create_symlink(dir.path, dir.path / "to_dir");
  e = error_of([&] { resolve_output(dir.path / "to_dir"); });
  EXPECT_NE(e.find("links to"), std::string::npos) << e;

  const fs::path socket_path = dir.path / "s.sock";
  const int s = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::strncpy(address.sun_path, socket_path.c_str(), sizeof address.sun_path - 1);
  ASSERT_EQ(::bind(s, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
  e = error_of([&] { write_output_file(socket_path, "x"); });
  EXPECT_NE(e.find("a socket"), std::string::npos) << e;
  EXPECT_TRUE(fs::is_socket(socket_path));
  ::close(s);

  const fs::path block = dir.path / "loop0";
  MAKE_NODE_OR_SKIP(block, S_IFBLK, 7, 0);
  e = error_of([&] { write_output_file(block, "x"); });
  EXPECT_NE(e.find("a block device"), std::string::npos) << e;
  EXPECT_TRUE(fs::is_block_file(block));
}

}  // namespace
}  // namespace slamvdb
#undef MAKE_NODE_OR_SKIP
