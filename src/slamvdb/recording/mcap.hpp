#pragma once
// MCAP files (https://mcap.dev/spec), read without an MCAP library (Debian 12 packages none; the
// reader is small and written from the specification): chunks uncompressed, lz4 or zstd; with a
// summary section (channels and statistics from it, chunks read through their chunk index in
// log-time order, chunks holding no selected channel skipped unread) or without one (a file still
// being written or cut short: scanned once to list its channels, then read linearly, with a note).
// Profiles `ros1` (message encoding "ros1") and `ros2` (message encoding "cdr"); channels in other
// encodings (json, protobuf, ...) are listed as Serialization::kOther.
#include <filesystem>
#include <memory>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

// Throws Error naming the file when it is not an MCAP file or is damaged.
std::unique_ptr<RecordingReader> open_mcap(const std::filesystem::path& path);

}  // namespace slamvdb::recording
