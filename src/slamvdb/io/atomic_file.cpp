#include "slamvdb/io/atomic_file.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <string>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kTempTag = ".tmp-";

fs::path make_temp_path(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  return target.parent_path() /
         fmt::format(".{}{}{}-{}", target.filename().string(), kTempTag, ::getpid(), counter.fetch_add(1));
}

fs::path directory_of(const fs::path& target) {
  return target.parent_path().empty() ? fs::path(".") : target.parent_path();
}

// PID of a temporary's writer, or 0 if `name` is not a temporary's name.
pid_t writer_pid(const std::string& name) {
  if (name.size() < 2 || name[0] != '.') return 0;
  const auto tag = name.rfind(kTempTag);
  if (tag == std::string::npos || tag < 2) return 0;
  const char* p = name.data() + tag + kTempTag.size();
  const char* end = name.data() + name.size();
  long pid = 0;
  unsigned n = 0;
  const auto [dash, ec] = std::from_chars(p, end, pid);
  if (ec != std::errc() || dash == end || *dash != '-' || pid <= 0) return 0;
  const auto [last, ec2] = std::from_chars(dash + 1, end, n);
  if (ec2 != std::errc() || last != end) return 0;
  return static_cast<pid_t>(pid);
}

}  // namespace

AtomicFile::AtomicFile(fs::path target, AtomicWriteOptions options)
    : target_(std::move(target)), options_(options) {
  if (target_.filename().empty()) throw Error(fmt::format("cannot write {}: not a file name", target_));
  temp_ = make_temp_path(target_);
  do fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  while (fd_ < 0 && errno == EINTR);
  if (fd_ < 0) {
    const int error = errno;
    if (error == ENOENT || error == ENOTDIR)
      throw Error(fmt::format("cannot write {}: directory {} does not exist", target_, directory_of(target_)));
    throw Error(fmt::format("cannot write {}: cannot create a file in {}: {}", target_, directory_of(target_),
                            std::strerror(error)));
  }
}

AtomicFile::~AtomicFile() {
  if (!committed_) discard();
}

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temp_.empty()) ::unlink(temp_.c_str());
}

void AtomicFile::write(const void* data, std::size_t bytes) {
  if (fd_ < 0) throw Error(fmt::format("cannot write {}: already committed", target_));
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd_, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      discard();
      throw Error(fmt::format("cannot write {}: {}", target_, std::strerror(error)));
    }
    p += n;
    bytes -= static_cast<std::size_t>(n);
  }
}

void AtomicFile::commit() {
  if (fd_ < 0) throw Error(fmt::format("cannot write {}: already committed or failed", target_));
  // Delayed allocation can report a full disk only at fsync or close, so both are checked.
  if (options_.sync && ::fsync(fd_) != 0) {
    const int error = errno;
    discard();
    throw Error(fmt::format("cannot write {}: {}", target_, std::strerror(error)));
  }
  const int closed = ::close(fd_);
  fd_ = -1;
  if (closed != 0) {
    const int error = errno;
    discard();
    throw Error(fmt::format("cannot write {}: {}", target_, std::strerror(error)));
  }
  if (::rename(temp_.c_str(), target_.c_str()) != 0) {
    const int error = errno;
    discard();
    throw Error(fmt::format("cannot write {}: cannot rename the finished temporary file over it: {}", target_,
                            std::strerror(error)));
  }
  committed_ = true;
  if (options_.sync) sync_directory(directory_of(target_));
}

void write_file_atomically(const fs::path& target, std::string_view bytes, AtomicWriteOptions options) {
  AtomicFile file(target, options);
  file.write(bytes);
  file.commit();
}

void write_file_atomically_with(const fs::path& target, const std::function<void(const fs::path& temp)>& write,
                                AtomicWriteOptions options) {
  AtomicFile file(target, options);
  write(file.temp_path());
  file.commit();
}

bool is_atomic_temp_file(const fs::path& path) { return writer_pid(path.filename().string()) != 0; }

std::size_t remove_stale_temp_files(const fs::path& dir) {
  std::size_t removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const pid_t pid = writer_pid(it->path().filename().string());
    if (pid == 0 || pid == ::getpid()) continue;
    // kill(pid, 0) fails with ESRCH only when no such process exists (EPERM: it runs as another user).
    if (::kill(pid, 0) == 0 || errno != ESRCH) continue;
    std::error_code remove_error;
    if (it->is_regular_file(remove_error) && fs::remove(it->path(), remove_error)) ++removed;
  }
  if (ec) throw Error(fmt::format("cannot list {} to remove stale temporary files: {}", dir, ec.message()));
  return removed;
}

void sync_directory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw Error(fmt::format("cannot open directory {} to sync it: {}", dir, std::strerror(errno)));
  const int synced = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (synced != 0) throw Error(fmt::format("cannot sync directory {}: {}", dir, std::strerror(error)));
}

void sync_file_system(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw Error(fmt::format("cannot open {} to sync its file system: {}", path, std::strerror(errno)));
  const int synced = ::syncfs(fd);
  const int error = errno;
  ::close(fd);
  if (synced != 0) throw Error(fmt::format("cannot sync the file system of {}: {}", path, std::strerror(error)));
}

}  // namespace slamvdb
