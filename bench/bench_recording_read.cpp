// Reading recordings: every message of an MCAP of a SIMULATED drive (40 m, 80 scans of 64 x 1024
// points as PointCloud2, images, odometry; written by @mcap/core through
// tests/recording_fixtures/write_mcap.mjs, ROS 2 profile) with uncompressed, lz4 and zstd chunks,
// in MB/s of message bytes delivered on one core, beside the physical references: memcpy of the
// same bytes, and decompressing the same chunks alone (LZ4F_decompress / ZSTD_decompressDCtx, via
// the reader's Decompressor, the calls it makes). The files are made once per run in $TMPDIR
// (about 20 s); without node and the fixtures' npm packages the benchmarks are skipped.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/recording/decompress.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/synth/sequence_writer.hpp"

namespace slamvdb::bench {
namespace {

namespace fs = std::filesystem;

struct RecordingFiles {
  fs::path dir;
  std::map<std::string, fs::path> mcap;  // by chunk compression
  std::string error;
  RecordingFiles() {
    dir = fs::temp_directory_path() / ("slamvdb-bench-recording-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    synth::SynthConfig config;
    config.length_m = 40.0;
    synth::write_synthetic_sequence(config, dir / "seq", true);
    const fs::path script = fs::path(SLAMVDB_SOURCE_DIR) / "tests" / "recording_fixtures" / "write_mcap.mjs";
    for (const std::string compression : {"none", "lz4", "zstd"}) {
      const fs::path out = dir / (compression + ".mcap");
      const std::string command = "node '" + script.string() + "' '" + (dir / "seq").string() + "' '" + out.string() +
                                  "' --compression " + compression + " > /dev/null 2>&1";
      if (std::system(command.c_str()) != 0) {
        error = "cannot run " + script.string() + " (node and its npm packages: scripts/setup.sh)";
        return;
      }
      mcap[compression] = out;
    }
    fs::remove_all(dir / "seq");
  }
  ~RecordingFiles() { fs::remove_all(dir); }
};

const RecordingFiles& files() {
  static const RecordingFiles f;
  return f;
}

// Reads every message; returns the bytes delivered.
std::uint64_t read_all(const fs::path& file) {
  const auto reader = recording::open_mcap(file);
  recording::Message m;
  std::uint64_t bytes = 0;
  while (reader->next(m)) {
    bytes += m.data.size();
    benchmark::DoNotOptimize(m.data.data());
  }
  return bytes;
}

void BM_RecordingReadMcap(benchmark::State& state, const std::string& compression) {
  if (!files().error.empty()) {
    state.SkipWithError(files().error.c_str());
    return;
  }
  const fs::path file = files().mcap.at(compression);
  std::uint64_t bytes = 0;
  for (auto _ : state) bytes += read_all(file);
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.counters["file_MB"] = static_cast<double>(fs::file_size(file)) / 1e6;
}
BENCHMARK_CAPTURE(BM_RecordingReadMcap, uncompressed, std::string("none"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RecordingReadMcap, lz4, std::string("lz4"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RecordingReadMcap, zstd, std::string("zstd"))->Unit(benchmark::kMillisecond);

// memcpy of as many bytes as the recording's messages, in pieces of a message's size.
void BM_RecordingMemcpyReference(benchmark::State& state) {
  if (!files().error.empty()) {
    state.SkipWithError(files().error.c_str());
    return;
  }
  std::vector<std::size_t> sizes;
  {
    const auto reader = recording::open_mcap(files().mcap.at("none"));
    recording::Message m;
    while (reader->next(m)) sizes.push_back(m.data.size());
  }
  std::size_t total = 0;
  for (const std::size_t s : sizes) total += s;
  std::vector<char> from(total, 1), to(total);
  std::uint64_t bytes = 0;
  for (auto _ : state) {
    std::size_t at = 0;
    for (const std::size_t s : sizes) {
      std::memcpy(to.data() + at, from.data() + at, s);
      at += s;
    }
    benchmark::DoNotOptimize(to.data());
    bytes += total;
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
}
BENCHMARK(BM_RecordingMemcpyReference)->Unit(benchmark::kMillisecond);

// The chunks' compressed records, taken out of the file (top-level Chunk records).
struct Chunks {
  std::vector<std::string> packed;
  std::vector<std::size_t> unpacked_size;
};
Chunks chunks_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string b{std::istreambuf_iterator<char>(in), {}};
  auto u64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
    return v;
  };
  Chunks c;
  for (std::size_t pos = 8; pos + 9 < b.size();) {
    const int op = static_cast<unsigned char>(b[pos]);
    const std::uint64_t length = u64(pos + 1);
    if (op == 0x02) break;
    if (op == 0x06) {
      const std::size_t name = pos + 9 + 28;
      const std::uint32_t name_length = static_cast<std::uint32_t>(u64(name) & 0xffffffffu);
      const std::size_t records = name + 4 + name_length;
      c.unpacked_size.push_back(u64(pos + 9 + 16));
      c.packed.push_back(b.substr(records + 8, u64(records)));
    }
    pos += 9 + length;
  }
  return c;
}

void BM_RecordingDecompressReference(benchmark::State& state, const std::string& compression) {
  if (!files().error.empty()) {
    state.SkipWithError(files().error.c_str());
    return;
  }
  const Chunks chunks = chunks_of(files().mcap.at(compression));
  recording::Decompressor decompressor;
  recording::ByteBuffer out;
  std::uint64_t bytes = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < chunks.packed.size(); ++i) {
      out.resize(chunks.unpacked_size[i], "benchmark");
      const std::span<const std::uint8_t> in(reinterpret_cast<const std::uint8_t*>(chunks.packed[i].data()),
                                             chunks.packed[i].size());
      if (compression == "zstd")
        decompressor.zstd_exact(in, out.span(), "benchmark");
      else
        decompressor.lz4_frame_exact(in, out.span(), "benchmark");
      bytes += out.size();
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.counters["chunks"] = static_cast<double>(chunks.packed.size());
}
BENCHMARK_CAPTURE(BM_RecordingDecompressReference, lz4, std::string("lz4"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RecordingDecompressReference, zstd, std::string("zstd"))->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace slamvdb::bench
