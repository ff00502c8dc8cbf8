#pragma once
// Writing a dataset folder as an MCAP recording, shared by `slamvdb convert` and
// `slamvdb synth --format mcap`: the options (--compression, --chunk-size) and the run (progress
// bar, summary lines, write speed).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

#include "option_checks.hpp"
#include "progress.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/sensors/mcap_export.hpp"

namespace slamvdb::cli {

struct McapOutputOptions {
  std::string compression = "zstd";
  double chunk_mb = 4.0;
  McapExportOptions export_options() const {
    return {compression == "none" ? std::string() : compression, static_cast<std::uint64_t>(chunk_mb * 1e6)};
  }
};

inline void add_mcap_output_options(CLI::App* cmd, McapOutputOptions& options) {
  cmd->add_option("--compression", options.compression, "MCAP chunk compression")
      ->capture_default_str()
      ->check(CLI::IsMember({"zstd", "none"}));
  cmd->add_option("--chunk-size", options.chunk_mb,
                  "MCAP chunk size in MB (uncompressed; a larger message gets its own)")
      ->capture_default_str()
      ->check(finite_range(0.001, 1024));
}

// Reads the dataset folder `folder` and writes it to `out` as an MCAP recording; prints what it
// wrote. `what` labels the progress bar and the first line ("SIMULATED drive", "sequence").
inline void write_folder_as_mcap(const std::filesystem::path& folder, const std::filesystem::path& out,
                                 const McapOutputOptions& options, const std::string& what) {
  const Sequence sequence = read_sequence(folder);
  const auto start = std::chrono::steady_clock::now();
  std::optional<ProgressBar> bar;
  const McapExportSummary s =
      write_sequence_mcap(sequence, out, options.export_options(), [&](std::size_t done, std::size_t total) {
        if (!bar) bar.emplace("mcap", total, "frames");
        bar->update(done);
      });
  if (bar) bar->finish();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s written to %s as a ROS 2 MCAP recording in %.1f s (%.1f MB, %.0f MB/s of messages; %s chunks)\n",
              what.c_str(), out.c_str(), seconds, static_cast<double>(s.bytes) / 1e6,
              seconds > 0 ? static_cast<double>(s.uncompressed_bytes) / 1e6 / seconds : 0.0,
              options.compression == "none" ? "uncompressed" : options.compression.c_str());
  for (const auto& [topic, count] : s.messages)
    std::printf("  %-40s %llu messages\n", topic.c_str(), static_cast<unsigned long long>(count));
}

}  // namespace slamvdb::cli
