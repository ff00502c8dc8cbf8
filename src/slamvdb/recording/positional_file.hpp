#pragma once
// A recording's file read at given offsets (pread), for readers that jump between chunks and index
// records: 64-bit offsets (files over 4 GB), opened through RegularFile (a FIFO or a directory is a
// clear Error), every read bounds-checked against the size at open, every failure an Error naming
// the file and the offset. Counts the bytes it reads, for progress.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "slamvdb/core/regular_file.hpp"

namespace slamvdb::recording {

class PositionalFile {
 public:
  // `what` names the kind of file in messages ("MCAP file", "ROS 2 bag file", ...).
  PositionalFile(const std::filesystem::path& path, std::string_view what);

  std::uint64_t size() const { return file_.size(); }
  const std::filesystem::path& path() const { return file_.path(); }
  // "MCAP file "/x/y.mcap"": how messages name the file.
  const std::string& name() const { return name_; }
  std::uint64_t bytes_read() const { return bytes_read_; }

  // Reads exactly `bytes` at `offset`; throws Error if that range is not inside the file (naming
  // `what_for`, e.g. "the Chunk record at offset 1234") or the read fails.
  void read_at(std::uint64_t offset, void* destination, std::size_t bytes, std::string_view what_for);
  // Whether [offset, offset + bytes) lies inside the file (no overflow).
  bool contains(std::uint64_t offset, std::uint64_t bytes) const {
    return offset <= size() && bytes <= size() - offset;
  }

 private:
  RegularFile file_;
  std::string name_;
  std::uint64_t bytes_read_ = 0;
};

}  // namespace slamvdb::recording
