#pragma once
// For the CLI tests of outputs: one small SIMULATED sequence, a map of it and a query set trained
// on it, made once per test suite, and helpers to run commands and compare files.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

class CliFiles : public ::testing::Test {
 public:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("slamvdb_cli_files_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    synth::SynthConfig config;
    config.seed = 3;
    config.length_m = 30.0;  // 60 scans: 6 s at sensor rate (`map --realtime` in the lock test)
    config.image_width = 64;
    config.image_height = 40;
    config.lidar.columns = 512;  // odometry (odometry, slam) needs more than 256
    synth::write_synthetic_sequence(config, seq(), true);
    const auto mapped = run_cli("map " + q(seq()) + " -o " + q(map()) + kMapOptions + " --quiet");
    ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
#ifdef SLAMVDB_WITH_TRAINING
    const auto trained = run_cli("train-queries " + q(seq()) + " -o " + q(queries()) + kTrainOptions + " --quiet");
    ASSERT_EQ(trained.exit_code, 0) << trained.output;
#else
    // Builds without Torch (the sanitizer builds) have no train-queries: a query set of one-hot
    // vectors in the map's embedding space serves every command that reads one.
    QuerySet set;
    set.model_id = read_map_summary(map()).info.model_id;
    set.names = {"grass", "tree", "bush", "dirt", "sky"};
    set.vectors = QueryMatrix::Identity(5, 16);
    save_query_set(queries(), set);
#endif
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir_); }

  static std::filesystem::path file(const std::string& name) { return dir_ / name; }
  static std::filesystem::path seq() { return dir_ / "seq"; }
  static std::filesystem::path map() { return dir_ / "m.svdb"; }
  static std::filesystem::path queries() { return dir_ / "q.json"; }
  static std::string q(const std::filesystem::path& p) { return quote_path(p); }

  static std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  static bool is_char_device(const std::filesystem::path& p) {
    struct stat st {};
    return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
  }
  // A character device node (1, 3: /dev/null; 1, 7: /dev/full); false where mknod is not allowed.
  static bool make_char_device(const std::filesystem::path& p, unsigned minor) {
    std::filesystem::remove(p);
    return ::mknod(p.c_str(), S_IFCHR | 0666, makedev(1, minor)) == 0;
  }

  // Options that keep the runs small (and the same for every command that makes features).
  static constexpr const char* kMapOptions = " --dim 16 --feature-size 64x40";
  static constexpr const char* kTrainOptions =
      " --dim 16 --feature-size 64x40 --epochs 1 --pixels-per-image 200 --val-fraction 0";

  static inline std::filesystem::path dir_;
};

}  // namespace slamvdb::testing
