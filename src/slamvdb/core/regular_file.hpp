#pragma once
// Opening input files safely. Every reader goes through here, so that a FIFO, a directory or a
// device given where a data file is expected is a clear Error instead of a read that blocks
// forever (a named pipe nobody writes to) or never ends (/dev/zero): the file is opened with
// O_NONBLOCK (opening a FIFO cannot wait for a writer), checked with fstat on the open descriptor
// (no window between check and use), and read with a size bound.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace slamvdb {

// Largest file read whole into memory by default (text files, manifests, YAML, images): 1 GiB.
// Bigger inputs of these kinds are malformed; the binary readers bound by their own headers.
inline constexpr std::uint64_t kMaxReadBytes = std::uint64_t{1} << 30;

// A regular file opened read-only. `what` names the kind of file in messages ("scan file",
// "camera intrinsics", ...); every Error reads "<what> <path> ...".
class RegularFile {
 public:
  // Throws Error if the path is missing, is not a regular file after following symlinks (the
  // message names what it is: a directory, a FIFO, a character device, ...) or cannot be opened.
  RegularFile(const std::filesystem::path& path, std::string_view what);
  ~RegularFile();
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;

  int fd() const { return fd_; }
  std::uint64_t size() const { return size_; }  // at open time
  const std::filesystem::path& path() const { return path_; }
  const std::string& what() const { return what_; }

  // Reads exactly `bytes` bytes from the current offset; throws Error naming the file on a read
  // error or if the file ends first (it shrank while being read).
  void read_exact(void* destination, std::size_t bytes);
  // The whole file; throws Error if it is larger than `max_bytes`.
  std::string read_all(std::uint64_t max_bytes = kMaxReadBytes);

 private:
  std::filesystem::path path_;
  std::string what_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

// The whole content of a regular file (see RegularFile).
std::string read_regular_file(const std::filesystem::path& path, std::string_view what,
                              std::uint64_t max_bytes = kMaxReadBytes);

// Throws the same Error as RegularFile unless `path` is a regular file; opens nothing.
void require_regular_file(const std::filesystem::path& path, std::string_view what);

// "a directory", "a FIFO (named pipe)", ... for the file type bits of a stat mode.
std::string_view describe_file_type(unsigned mode);

}  // namespace slamvdb
