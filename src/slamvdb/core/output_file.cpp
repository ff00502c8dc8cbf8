#include "slamvdb/core/output_file.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <ctime>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace fs = std::filesystem;

namespace output_file_detail {

constexpr std::string_view kTempTag = ".tmp-";

fs::path directory_of(const fs::path& file) { return file.parent_path().empty() ? fs::path(".") : file.parent_path(); }

// PID of a temporary's writer, or 0 if `name` is not a temporary's name (".NAME.tmp-PID-N").
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

// A write to a pipe whose reader has gone raises SIGPIPE, which kills the process without a word.
// While it is blocked the write fails with EPIPE instead, reported like any other write error; a
// SIGPIPE raised meanwhile is consumed (unless one was already pending) before the mask is restored.
class SigpipeBlocked {
 public:
  SigpipeBlocked() {
    sigemptyset(&pipe_);
    sigaddset(&pipe_, SIGPIPE);
    sigset_t pending;
    sigemptyset(&pending);
    pending_before_ = sigpending(&pending) == 0 && sigismember(&pending, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_, &old_);
  }
  ~SigpipeBlocked() {
    if (!pending_before_) {
      const timespec zero{0, 0};
      while (sigtimedwait(&pipe_, nullptr, &zero) == SIGPIPE) {
      }
    }
    pthread_sigmask(SIG_SETMASK, &old_, nullptr);
  }
  SigpipeBlocked(const SigpipeBlocked&) = delete;
  SigpipeBlocked& operator=(const SigpipeBlocked&) = delete;

 private:
  sigset_t pipe_, old_;
  bool pending_before_ = false;
};

}  // namespace output_file_detail

namespace ofd = output_file_detail;

OutputFile::OutputFile(fs::path target, OutputOptions options) : target_(std::move(target)), options_(options) {
  destination_ = resolve_output(target_);
  if (!destination_.is_stream()) {
    open_named_temp(ofd::directory_of(destination_.resolved), destination_.kind == OutputKind::kRegularFile);
    return;
  }
  if (destination_.descriptor >= 0) {
    stream_fd_ = ::fcntl(destination_.descriptor, F_DUPFD_CLOEXEC, 3);
    if (stream_fd_ < 0) fail(fmt::format("cannot use {}: {}", destination_.what, std::strerror(errno)));
    return;
  }
  do stream_fd_ = ::open(destination_.resolved.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
  while (stream_fd_ < 0 && errno == EINTR);
  if (stream_fd_ < 0) fail(std::strerror(errno));
  // It was a device or FIFO a moment ago; if it was replaced since, writing into it in place would
  // be neither atomic nor a write-through.
  struct stat st {};
  if (::fstat(stream_fd_, &st) != 0 || !(S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)))
    fail("it was replaced by another kind of file while being opened");
}

OutputFile::~OutputFile() {
  if (!committed_) discard();
}

void OutputFile::open_named_temp(const fs::path& dir, bool replaces_regular_file) {
  static std::atomic<unsigned> counter{0};
  const std::string name = destination_.resolved.filename().empty() ? "output" : destination_.resolved.filename().string();
  for (int attempt = 0;; ++attempt) {
    temp_ = dir / fmt::format(".{}{}{}-{}", name, ofd::kTempTag, ::getpid(), counter.fetch_add(1));
    do fd_ = ::open(temp_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    while (fd_ < 0 && errno == EINTR);
    if (fd_ >= 0) break;
    const int error = errno;
    if (error == EEXIST && attempt < 100) continue;  // left by a killed process that had our PID
    temp_.clear();
    if (error == ENOENT || error == ENOTDIR) fail(fmt::format("directory {} does not exist", dir));
    fail(fmt::format("cannot create a file in {}: {}", dir, std::strerror(error)));
  }
  replaces_regular_file_ = replaces_regular_file;
}

// The replacement is the same file to its users: same permission bits, and same owner and group
// where this process may set them (root may; others keep their own, which is all they can do).
// Set at the end: a read-only file's mode would keep a writer that reopens the temporary by name
// (SQLite) from writing it.
void OutputFile::keep_permissions() noexcept {
  struct stat previous {};
  if (!replaces_regular_file_ || ::stat(destination_.resolved.c_str(), &previous) != 0 || !S_ISREG(previous.st_mode))
    return;
  if (::fchown(fd_, previous.st_uid, previous.st_gid) != 0) {
    // Not allowed (another owner): the file becomes ours, with the old permission bits.
  }
  ::fchmod(fd_, previous.st_mode & 07777);
}

const fs::path& OutputFile::temp_path() {
  if (committed_) throw Error(fmt::format("cannot write {}: already committed", target_));
  if (temp_.empty()) {
    if (stream_fd_ < 0) throw Error(fmt::format("cannot write {}: it failed before", target_));
    open_named_temp(fs::temp_directory_path(), false);
  }
  return temp_;
}

void OutputFile::write_all(int fd, const char* data, std::size_t bytes) {
  std::optional<ofd::SigpipeBlocked> blocked;
  if (fd == stream_fd_) blocked.emplace();
  while (bytes > 0) {
    const ssize_t n = ::write(fd, data, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      blocked.reset();
      fail(std::strerror(error));
    }
    data += n;
    bytes -= static_cast<std::size_t>(n);
  }
}

void OutputFile::write(const void* data, std::size_t bytes) {
  if (committed_ || (fd_ < 0 && stream_fd_ < 0))
    throw Error(fmt::format("cannot write {}: already committed or failed", target_));
  write_all(fd_ >= 0 ? fd_ : stream_fd_, static_cast<const char*>(data), bytes);
}

// The named temporary (written by a library that needed a file name) goes through to the stream.
void OutputFile::copy_temp_through() {
  const int in = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) fail(fmt::format("cannot read back the temporary file {}: {}", temp_, std::strerror(errno)));
  std::vector<char> buffer(std::size_t{1} << 20);
  while (true) {
    const ssize_t n = ::read(in, buffer.data(), buffer.size());
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      ::close(in);
      fail(fmt::format("cannot read back the temporary file {}: {}", temp_, std::strerror(error)));
    }
    try {
      write_all(stream_fd_, buffer.data(), static_cast<std::size_t>(n));
    } catch (...) {
      ::close(in);
      throw;
    }
  }
  ::close(in);
}

void OutputFile::commit() {
  if (committed_ || (fd_ < 0 && stream_fd_ < 0))
    throw Error(fmt::format("cannot write {}: already committed or failed", target_));
  if (destination_.is_stream()) {
    if (!temp_.empty()) copy_temp_through();
    // Character devices and pipes have nothing to fsync; a close that fails (a full or failing
    // device that reports late) is a failed write.
    const int closed = ::close(stream_fd_);
    stream_fd_ = -1;
    if (closed != 0 && errno != EINTR) fail(std::strerror(errno));
    discard();  // the temporary, if any
    committed_ = true;
    return;
  }
  keep_permissions();
  // Delayed allocation can report a full disk only at fsync or close, so both are checked.
  if (options_.sync && ::fsync(fd_) != 0) fail(std::strerror(errno));
  const int closed = ::close(fd_);
  fd_ = -1;
  if (closed != 0) fail(std::strerror(errno));
  if (::rename(temp_.c_str(), destination_.resolved.c_str()) != 0)
    fail(fmt::format("cannot rename the finished temporary file over it: {}", std::strerror(errno)));
  temp_.clear();
  committed_ = true;
  if (options_.sync) sync_directory(ofd::directory_of(destination_.resolved));
}

void OutputFile::fail(const std::string& reason) {
  discard();
  throw Error(fmt::format("cannot write {}: {}", target_, reason));
}

void OutputFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (stream_fd_ >= 0) ::close(stream_fd_);
  stream_fd_ = -1;
  if (!temp_.empty()) ::unlink(temp_.c_str());
  temp_.clear();
}

void write_output_file(const fs::path& target, std::string_view bytes, OutputOptions options) {
  OutputFile file(target, options);
  file.write(bytes);
  file.commit();
}

void write_output_file_with(const fs::path& target, const std::function<void(const fs::path& file)>& write,
                            OutputOptions options) {
  OutputFile file(target, options);
  write(file.temp_path());
  file.commit();
}

bool is_output_temp_file(const fs::path& path) { return ofd::writer_pid(path.filename().string()) != 0; }

std::size_t remove_stale_temp_files(const fs::path& dir, std::string_view of_file) {
  const std::string prefix = of_file.empty() ? std::string() : fmt::format(".{}{}", of_file, ofd::kTempTag);
  std::size_t removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.starts_with(prefix)) continue;
    const pid_t pid = ofd::writer_pid(name);
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
