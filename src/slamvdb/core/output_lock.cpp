#include "slamvdb/core/output_lock.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"

namespace slamvdb {

namespace fs = std::filesystem;

namespace output_lock_detail {

// "PID 123: slamvdb map seq -o m.svdb" (the command line from /proc, arguments joined by spaces,
// cut at 300 characters).
std::string holder_line() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string command(std::istreambuf_iterator<char>(in), {});
  while (!command.empty() && command.back() == '\0') command.pop_back();
  for (char& c : command)
    if (c == '\0') c = ' ';
  if (command.size() > 300) command = command.substr(0, 300) + "...";
  return fmt::format("PID {}: {}\n", ::getpid(), command);
}

// What the holder wrote; it writes right after taking the lock, so an empty file is read again.
std::string read_holder(int fd) {
  std::string text;
  for (int attempt = 0; attempt < 20 && text.empty(); ++attempt) {
    if (attempt) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    char buffer[512];
    const ssize_t n = ::pread(fd, buffer, sizeof buffer, 0);
    if (n > 0) text.assign(buffer, static_cast<std::size_t>(n));
  }
  while (!text.empty() && (text.back() == '\n' || text.back() == '\0')) text.pop_back();
  return text.empty() ? "PID unknown" : text;
}

}  // namespace output_lock_detail

fs::path output_lock_file(const fs::path& output) {
  fs::path file = output;
  try {
    file = resolve_output(output).resolved;
  } catch (const Error&) {
    // A folder (synth, demo): locked beside it too.
  }
  std::error_code ec;
  fs::path absolute = fs::weakly_canonical(fs::absolute(file), ec);
  if (ec) absolute = fs::absolute(file).lexically_normal();
  if (absolute.filename().empty()) absolute = absolute.parent_path();  // "out/"
  return absolute.parent_path() / fmt::format(".{}.lock", absolute.filename().string());
}

OutputLock::OutputLock(const fs::path& output) : lock_file_(output_lock_file(output)) {
  using namespace output_lock_detail;
  // A holder that ends removes the lock file while still holding it: a process that opened that
  // file meanwhile locks a file no longer at the path, sees so, and tries again.
  for (int attempt = 0;; ++attempt) {
    do fd_ = ::open(lock_file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    while (fd_ < 0 && errno == EINTR);
    if (fd_ < 0)
      throw Error(fmt::format("cannot lock {} for writing: cannot create {}: {}", output, lock_file_, std::strerror(errno)));
    int locked = 0;
    do locked = ::flock(fd_, LOCK_EX | LOCK_NB);
    while (locked != 0 && errno == EINTR);
    if (locked != 0) {
      const int error = errno;
      const std::string holder = error == EWOULDBLOCK ? read_holder(fd_) : std::string();
      ::close(fd_);
      fd_ = -1;
      if (error == EWOULDBLOCK)
        throw Error(fmt::format("{} is being written by another slamvdb run ({}); wait for it to end or write "
                                "elsewhere (lock file {})",
                                output, holder, lock_file_));
      throw Error(fmt::format("cannot lock {} for writing ({}): {}", output, lock_file_, std::strerror(error)));
    }
    struct stat held {}, at_path {};
    if (::fstat(fd_, &held) == 0 && ::lstat(lock_file_.c_str(), &at_path) == 0 && held.st_dev == at_path.st_dev &&
        held.st_ino == at_path.st_ino)
      break;
    ::close(fd_);
    fd_ = -1;
    if (attempt == 100) throw Error(fmt::format("cannot lock {} for writing: {} keeps changing", output, lock_file_));
  }
  const std::string holder = holder_line();
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, holder.data(), holder.size(), 0) != static_cast<ssize_t>(holder.size())) {
    const int error = errno;
    ::unlink(lock_file_.c_str());
    ::close(fd_);
    throw Error(fmt::format("cannot lock {} for writing: cannot write {}: {}", output, lock_file_, std::strerror(error)));
  }
}

OutputLock::~OutputLock() {
  if (fd_ < 0) return;
  ::unlink(lock_file_.c_str());  // while still held: see the constructor
  ::close(fd_);
}

}  // namespace slamvdb
