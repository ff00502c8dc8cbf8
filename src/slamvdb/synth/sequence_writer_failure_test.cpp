// A synth run that fails (file size limit, full disk) or is killed must leave nothing that looks
// like a complete sequence: `slamvdb map` refuses what it left.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/mount.h>

#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::synth {
namespace {

namespace fs = std::filesystem;
using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

const std::string kCliPath = SLAMVDB_CLI_PATH;

std::string synth_command(const fs::path& out, const std::string& limits) {
  return fmt::format("{} exec {} synth {} --length 3 --image-size 64x40", limits, shell_quote(kCliPath),
                     shell_quote(out.string()));
}

// No file under its final name is a partial write: every scan file holds whole points and no
// temporary is left behind.
void expect_no_partial_files(const fs::path& out) {
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    if (!entry.is_regular_file()) continue;
    EXPECT_FALSE(is_output_temp_file(entry.path())) << entry.path();
    if (entry.path().extension() == ".bin") {
      EXPECT_GT(entry.file_size(), 0u) << entry.path();
      EXPECT_EQ(entry.file_size() % 16, 0u) << entry.path();
    }
  }
}

void expect_map_refuses(const fs::path& out) {
  const auto map = run_command(fmt::format("exec {} map {} -o {}", shell_quote(kCliPath), shell_quote(out.string()),
                                           shell_quote((out.parent_path() / "refused.svdb").string())));
  EXPECT_EQ(map.exit_code, 1) << map.output;
  EXPECT_NE(map.output.find("incomplete"), std::string::npos) << map.output;
  EXPECT_FALSE(fs::exists(out.parent_path() / "refused.svdb"));
}

TEST(SynthFailure, FileSizeLimitIsAnErrorAndLeavesAnIncompleteSequence) {
  slamvdb::testing::TempDir tmp;
  const fs::path out = tmp.path / "seq";
  // 400 blocks of 512 bytes: the small text files fit, the first scan (about 1 MB) does not.
  // SIGXFSZ ignored: the write fails with EFBIG, as on a full disk.
  const auto r = run_command(synth_command(out, "ulimit -f 400; trap '' XFSZ;"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("File too large"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out / kIncompleteMarker));
  expect_no_partial_files(out);
  expect_map_refuses(out);
  // A second run says what is there and replaces it with --force.
  const auto again = run_command(synth_command(out, ""));
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.output.find("incomplete sequence"), std::string::npos) << again.output;
  const auto forced = run_command(synth_command(out, "") + " --force");
  EXPECT_EQ(forced.exit_code, 0) << forced.output;
  EXPECT_FALSE(fs::exists(out / kIncompleteMarker));
  EXPECT_NO_THROW(read_sequence(out));
}

TEST(SynthFailure, AKilledRunLeavesAnIncompleteSequence) {
  slamvdb::testing::TempDir tmp;
  const fs::path out = tmp.path / "seq";
  // SIGXFSZ kills the writer in the middle of a write, like a crash.
  const auto r = run_command(synth_command(out, "ulimit -f 400;"));
  EXPECT_EQ(r.signal, SIGXFSZ) << r.exit_code << r.output;
  EXPECT_TRUE(fs::exists(out / kIncompleteMarker));
  expect_map_refuses(out);
}

TEST(SynthFailure, FullDiskIsAnErrorAndLeavesAnIncompleteSequence) {
  slamvdb::testing::TempDir tmp;
  const fs::path disk = tmp.path / "disk";
  fs::create_directories(disk);
  if (::mount("tmpfs", disk.c_str(), "tmpfs", 0, "size=2m") != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here (needs CAP_SYS_ADMIN)";
  struct Unmount {  // also when an assertion fails, so that the temporary folder can be removed
    fs::path dir;
    ~Unmount() { ::umount2(dir.c_str(), MNT_DETACH); }
  } unmount{disk};
  const fs::path out = disk / "seq";
  // The free-space check would refuse before writing; skip it to reach a real ENOSPC.
  const auto refused = run_command(synth_command(out, ""));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("MB free"), std::string::npos) << refused.output;
  const auto r = run_command(synth_command(out, "") + " --skip-space-check");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("No space left on device"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out / kIncompleteMarker));
  expect_no_partial_files(out);
  expect_map_refuses(out);
}

}  // namespace
}  // namespace slamvdb::synth
