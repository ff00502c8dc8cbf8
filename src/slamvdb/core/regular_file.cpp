#include "slamvdb/core/regular_file.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace {

[[noreturn]] void fail_errno(std::string_view what, const std::filesystem::path& path, int error) {
  if (error == ENOENT) throw Error(fmt::format("{} {} does not exist", what, path));
  if (error == ENOTDIR) throw Error(fmt::format("{} {} does not exist (a parent is not a directory)", what, path));
  throw Error(fmt::format("cannot open {} {}: {}", what, path, std::strerror(error)));
}

void require_regular(const struct stat& st, std::string_view what, const std::filesystem::path& path) {
  if (!S_ISREG(st.st_mode))
    throw Error(fmt::format("{} {} is {}, not a regular file", what, path, describe_file_type(st.st_mode)));
}

}  // namespace

std::string_view describe_file_type(unsigned mode) {
  switch (mode & S_IFMT) {
    case S_IFREG: return "a regular file";
    case S_IFDIR: return "a directory";
    case S_IFIFO: return "a FIFO (named pipe)";
    case S_IFCHR: return "a character device";
    case S_IFBLK: return "a block device";
    case S_IFSOCK: return "a socket";
    case S_IFLNK: return "a symbolic link";
  }
  return "of an unknown file type";
}

RegularFile::RegularFile(const std::filesystem::path& path, std::string_view what) : path_(path), what_(what) {
  // O_NONBLOCK: opening a FIFO read-only would otherwise wait for a writer. It has no effect on
  // regular files, the only kind kept.
  do fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  while (fd_ < 0 && errno == EINTR);
  if (fd_ < 0) fail_errno(what_, path_, errno);
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    const int error = errno;
    ::close(fd_);
    fail_errno(what_, path_, error);
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd_);
    require_regular(st, what_, path_);
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
}

RegularFile::~RegularFile() {
  if (fd_ >= 0) ::close(fd_);
}

void RegularFile::read_exact(void* destination, std::size_t bytes) {
  auto* out = static_cast<unsigned char*>(destination);
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::read(fd_, out + done, bytes - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw Error(fmt::format("cannot read {} {}: {}", what_, path_, std::strerror(errno)));
    }
    if (n == 0)
      throw Error(fmt::format("cannot read {} {}: the file ended after {} of {} bytes (did it change while being "
                              "read?)",
                              what_, path_, done, bytes));
    done += static_cast<std::size_t>(n);
  }
}

std::string RegularFile::read_all(std::uint64_t max_bytes) {
  if (size_ > max_bytes)
    throw Error(fmt::format("{} {} is {} bytes, more than the {} bytes such a file can sensibly have", what_, path_,
                            size_, max_bytes));
  std::string bytes(static_cast<std::size_t>(size_), '\0');
  read_exact(bytes.data(), bytes.size());
  return bytes;
}

std::string read_regular_file(const std::filesystem::path& path, std::string_view what, std::uint64_t max_bytes) {
  RegularFile file(path, what);
  return file.read_all(max_bytes);
}

void require_regular_file(const std::filesystem::path& path, std::string_view what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail_errno(what, path, errno);
  require_regular(st, what, path);
}

}  // namespace slamvdb
