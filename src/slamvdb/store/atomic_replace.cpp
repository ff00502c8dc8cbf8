#include "slamvdb/store/atomic_replace.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <random>
#include <string>

#include "slamvdb/core/error.hpp"

namespace slamvdb::store {
namespace fs = std::filesystem;
namespace {

std::string errno_text() { return std::strerror(errno); }

// Temp files are hidden siblings of the target named after the saving process, so a reader never
// takes one for a map and a later save can tell which ones a killed process left behind.
std::string temp_prefix(const fs::path& target) { return fmt::format(".{}.tmp-", target.filename().string()); }

class TempFile {
 public:
  // Created like any new file (mode 0666 minus the umask), or with the permissions of the map it replaces.
  explicit TempFile(const fs::path& target) {
    std::random_device random;
    for (int attempt = 0;; ++attempt) {
      const fs::path name = target.parent_path() / fmt::format("{}{}-{:08x}", temp_prefix(target), getpid(), random());
      const int fd = ::open(name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd >= 0) {
        ::close(fd);
        path_ = name;
        break;
      }
      if (errno != EEXIST || attempt == 100)
        throw Error(fmt::format("cannot create a temp file {}: {}", name.string(), errno_text()));
    }
    std::error_code ec;
    const fs::file_status previous = fs::status(target, ec);
    if (!ec && fs::is_regular_file(previous)) fs::permissions(path_, previous.permissions(), ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    std::error_code ignored;
    if (!path_.empty()) fs::remove(path_, ignored);
  }
  const fs::path& path() const { return path_; }
  void release() { path_.clear(); }

 private:
  fs::path path_;
};

}  // namespace

void fsync_path(const fs::path& p, bool directory) {
  const int fd = ::open(p.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) throw Error(fmt::format("cannot open {} to sync it: {}", p.string(), errno_text()));
  const int rc = ::fsync(fd);
  const std::string reason = rc != 0 ? errno_text() : std::string();
  ::close(fd);
  if (rc != 0) throw Error(fmt::format("fsync of {} failed: {}", p.string(), reason));
}

void remove_stale_temp_files(const fs::path& target) {
  const std::string prefix = temp_prefix(target);
  std::error_code ec;
  for (auto it = fs::directory_iterator(target.parent_path(), ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.starts_with(prefix)) continue;
    int pid = 0;
    const char* digits = name.data() + prefix.size();
    const auto [end, err] = std::from_chars(digits, name.data() + name.size(), pid);
    if (err != std::errc() || *end != '-' || pid <= 0 || pid == getpid()) continue;
    if (::kill(pid, 0) == 0 || errno != ESRCH) continue;  // its writer may still be running
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}


void replace_atomically(const fs::path& path, const std::function<void(const fs::path& temp)>& write) {
  const fs::path target = fs::absolute(path);
  remove_stale_temp_files(target);
  TempFile temp(target);
  write(temp.path());
  fsync_path(temp.path(), false);
  if (::rename(temp.path().c_str(), target.c_str()) != 0)
    throw Error(fmt::format("cannot rename {} over it: {}", temp.path().string(), errno_text()));
  temp.release();
  fsync_path(target.parent_path(), true);
}

}  // namespace slamvdb::store
