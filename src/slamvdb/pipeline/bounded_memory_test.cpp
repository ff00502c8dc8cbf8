// Memory stays bounded on long drives by default: `slamvdb map` lets finished submaps far from the
// vehicle leave memory (the map file it writes while mapping holds them), without being asked to.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <iostream>
#include <string>

#include "slamvdb/pipeline/mapper.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

// The count printed right before `label` in `text` (-1 when absent).
long count_before(const std::string& text, const std::string& label) {
  const std::size_t at = text.find(label);
  if (at == std::string::npos) return -1;
  std::size_t begin = at;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(text[begin - 1]))) --begin;
  return begin == at ? -1 : std::atol(text.c_str() + begin);
}

TEST(BoundedMemory, LongDrivesKeepOnlyNearSubmapsInMemoryByDefault) {
  testing::TempDir tmp;
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH);
  const std::string seq = shell_quote((tmp.path / "seq").string()), map = shell_quote((tmp.path / "m.svdb").string());
  // A 1.3 km loop (about 410 m across): its far side lies well beyond the default unload radius.
  // Sparse sensors keep it quick; the submaps are the default 50 m.
  const auto synth = run_command(cli + " --quiet synth " + seq + " --length 1300 --speed 40 --camera-rate 1 " +
                                     "--image-size 64x40 --lidar-columns " + std::to_string(testing::test_size(256, 128)) +
                                     " 2>&1",
                                 600);
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const auto mapped =
      run_command(cli + " map " + seq + " -o " + map + " --dim 8 --feature-size 16x10 2>&1", 600);  // default radius
  ASSERT_EQ(mapped.exit_code, 0) << mapped.output;

  const MapFileSummary saved = read_map_summary(tmp.path / "m.svdb");
  const long submaps = static_cast<long>(saved.submaps.size());
  const long peak = count_before(mapped.output, " in memory at once");
  const long left = count_before(mapped.output, " times one left memory");
  std::cout << mapped.output.substr(mapped.output.find("submaps: ")).substr(0, 160) << "\n";
  ASSERT_GE(submaps, 24) << mapped.output;  // 1.3 km in 50 m submaps
  EXPECT_EQ(count_before(mapped.output, ", at most"), submaps) << mapped.output;  // "submaps: N, at most ..."
  EXPECT_GT(peak, 0) << mapped.output;
  EXPECT_LE(peak, submaps / 2) << mapped.output;  // bounded: the near part of the loop only
  EXPECT_GE(left, submaps / 2) << mapped.output;  // each far submap left memory at least once
  // The file holds every submap, and they load back and check out.
  if (!testing::sanitizer_test_scale()) {
    const auto check = run_command(cli + " info " + map + " --check 2>&1", 600);
    EXPECT_EQ(check.exit_code, 0) << check.output;
  } else {
    // Under the sanitizers, --check's validation without its world figures (the occupancy of all
    // submaps combined, most of a 77-s check under ASan; `info --check` itself runs in
    // MapValidationTest): `info`, then load_map, which reads and validates every row as --check does.
    const auto info = run_command(cli + " info " + map + " 2>&1", 600);
    EXPECT_EQ(info.exit_code, 0) << info.output;
    const SemanticMap loaded = load_map(tmp.path / "m.svdb");
    EXPECT_EQ(static_cast<long>(loaded.num_submaps()), submaps);
    std::size_t known = 0;
    for (const SubmapInfo& s : loaded.submaps())
      loaded.read_submap(s.id, [&](const Submap& sm) { known += sm.voxels().occupancy().num_known_voxels(); });
    EXPECT_EQ(known, saved.known_voxels);
  }
  static_assert(kDefaultUnloadRadius > 0, "the default bounds memory");
}

}  // namespace
}  // namespace slamvdb
