// resolve_output: what an output path is (output_file.hpp has the rule).
#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <optional>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb {

namespace fs = std::filesystem;

namespace output_target_detail {

// Linux follows at most 40 symbolic links in one path resolution; so does this.
constexpr int kMaxLinkHops = 40;

std::optional<int> parse_descriptor(std::string_view digits) {
  int fd = -1;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), fd);
  if (ec != std::errc() || end != digits.data() + digits.size() || digits.empty() || fd < 0) return std::nullopt;
  return fd;
}

// /dev/stdout, /dev/stderr, /dev/stdin, /dev/fd/N, /proc/self/fd/N, /proc/<our pid>/fd/N: names of
// descriptors this process already has open. Opening them anew would not do what the shell set up
// (an append redirection, a pipe's shared offset), so the descriptor itself is written to.
std::optional<int> descriptor_alias(const fs::path& path) {
  const std::string p = path.lexically_normal().string();
  if (p == "/dev/stdin") return 0;
  if (p == "/dev/stdout") return 1;
  if (p == "/dev/stderr") return 2;
  for (const std::string& prefix : {std::string("/dev/fd/"), std::string("/proc/self/fd/"),
                                   fmt::format("/proc/{}/fd/", ::getpid())})
    if (p.starts_with(prefix)) return parse_descriptor(std::string_view(p).substr(prefix.size()));
  return std::nullopt;
}

std::string descriptor_name(int fd) {
  if (fd == 1) return "standard output";
  if (fd == 2) return "standard error";
  return fmt::format("open descriptor {}", fd);
}

[[noreturn]] void refuse(const fs::path& path, const fs::path& resolved, std::string_view what) {
  throw Error(fmt::format("cannot write {}: {} {}; outputs go to regular files (replaced atomically), character "
                          "devices and FIFOs (written through)",
                          path, resolved == path ? "it is" : fmt::format("it links to {}, which is", resolved), what));
}

}  // namespace output_target_detail

OutputTarget resolve_output(const fs::path& path) {
  using namespace output_target_detail;
  if (path.empty()) throw Error("cannot write an output with an empty file name");
  OutputTarget target;
  target.path = path;
  fs::path current = path;
  for (int hop = 0;; ++hop) {
    if (const auto fd = descriptor_alias(current)) {
      struct stat st {};
      if (::fstat(*fd, &st) != 0)
        throw Error(fmt::format("cannot write {}: descriptor {} is not open ({})", path, *fd, std::strerror(errno)));
      if (S_ISDIR(st.st_mode)) refuse(path, current, "a directory");
      target.kind = OutputKind::kStream;
      target.descriptor = *fd;
      target.resolved = current;
      target.what = descriptor_name(*fd);
      return target;
    }
    struct stat st {};
    if (::lstat(current.c_str(), &st) != 0) {
      const int error = errno;
      if (error == ENOENT) {
        if (current.filename().empty() || current.filename() == "." || current.filename() == "..")
          throw Error(fmt::format("cannot write {}: not a file name", path));
        target.kind = OutputKind::kNewFile;
        target.resolved = current;
        target.what = "a new file";
        return target;
      }
      if (error == ENOTDIR)
        throw Error(fmt::format("cannot write {}: a parent of {} is not a directory", path, current));
      throw Error(fmt::format("cannot write {}: {}", path, std::strerror(error)));
    }
    if (S_ISLNK(st.st_mode)) {
      if (hop >= kMaxLinkHops) throw Error(fmt::format("cannot write {}: too many levels of symbolic links", path));
      std::error_code ec;
      const fs::path link = fs::read_symlink(current, ec);
      if (ec) throw Error(fmt::format("cannot write {}: cannot read the symbolic link {}: {}", path, current, ec.message()));
      current = link.is_absolute() ? link : current.parent_path() / link;
      continue;
    }
    target.resolved = current;
    target.what = std::string(describe_file_type(st.st_mode));
    if (S_ISREG(st.st_mode)) {
      target.kind = OutputKind::kRegularFile;
      return target;
    }
    if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) {
      target.kind = OutputKind::kStream;
      return target;
    }
    refuse(path, current, target.what);
  }
}

}  // namespace slamvdb
