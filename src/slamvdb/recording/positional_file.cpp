#include "slamvdb/recording/positional_file.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "slamvdb/core/error.hpp"

namespace slamvdb::recording {

PositionalFile::PositionalFile(const std::filesystem::path& path, std::string_view what)
    : file_(path, what), name_(fmt::format("{} {}", what, path)) {}

void PositionalFile::read_at(std::uint64_t offset, void* destination, std::size_t bytes, std::string_view what_for) {
  if (!contains(offset, bytes))
    throw Error(fmt::format("{}: {} ({} bytes at offset {}) extends past the end of the file ({} bytes): the file "
                            "is truncated or damaged",
                            name_, what_for, bytes, offset, size()));
  auto* out = static_cast<unsigned char*>(destination);
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::pread(file_.fd(), out + done, bytes - done, static_cast<off_t>(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      throw Error(fmt::format("cannot read {} at offset {}: {}", name_, offset + done, std::strerror(errno)));
    }
    if (n == 0)
      throw Error(fmt::format("cannot read {}: it ended at offset {} while reading {} (did it change while being "
                              "read?)",
                              name_, offset + done, what_for));
    done += static_cast<std::size_t>(n);
  }
  bytes_read_ += bytes;
}

}  // namespace slamvdb::recording
