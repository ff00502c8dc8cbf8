// What `map` and `slam` record and say about how a map was made: the fusion rule it was fused with
// (the paper's by default) and the encoder's settings, and a warning when the SIMULATED encoder
// cannot have its view-dependent errors because the images lack synth's view geometry.
#include <filesystem>
#include <string>

#include "cli_files_fixture.hpp"
#include "slamvdb/io/rellis_reader.hpp"

namespace slamvdb::testing {
namespace {
namespace fs = std::filesystem;

class MappingRecords : public CliFiles {};

TEST_F(MappingRecords, MapsRecordTheRuleAndEncoderSettingsTheyWereMadeWith) {
  // The suite's map: default options.
  const MapFileSummary made = read_map_summary(map());
  EXPECT_EQ(made.info.fusion, "paper");
  EXPECT_NE(made.info.features.find("realistic (SIMULATED)"), std::string::npos) << made.info.features;

  const auto slam = run_cli("slam " + q(seq()) + " -o " + q(file("slam.svdb")) + kMapOptions +
                            " --fusion-weighting quality --sim-encoder clean --quiet");
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  const MapFileSummary slammed = read_map_summary(file("slam.svdb"));
  EXPECT_EQ(slammed.info.fusion, "quality");
  EXPECT_NE(slammed.info.features.find("clean (SIMULATED)"), std::string::npos) << slammed.info.features;

  const auto bad = run_cli("slam " + q(seq()) + " -o " + q(file("bad.svdb")) + " --fusion-weighting mean");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
}

TEST_F(MappingRecords, MapWarnsOnceWhenImagesLackTheSimulatedViewGeometry) {
  const std::string warning = "have no SIMULATED view geometry";
  const auto map_of = [&](const fs::path& sequence, const std::string& extra) {
    return run_cli("map " + q(sequence) + " -o " + q(file("view.svdb")) + kMapOptions +
                   " --max-scans 6 --no-checkpoints --quiet" + extra);
  };
  const auto with = map_of(seq(), "");
  ASSERT_EQ(with.exit_code, 0) << with.output;
  EXPECT_EQ(with.output.find(warning), std::string::npos) << with.output;

  // A sequence as synth wrote it before the view geometry existed.
  const fs::path old = file("seq-without-view");
  fs::copy(seq(), old, fs::copy_options::recursive);
  fs::remove_all(old / kRellisSimViewDir);
  const auto without = map_of(old, "");
  ASSERT_EQ(without.exit_code, 0) << without.output;
  const auto at = without.output.find(warning);
  ASSERT_NE(at, std::string::npos) << without.output;
  EXPECT_EQ(without.output.find(warning, at + 1), std::string::npos) << "once per run: " << without.output;
  // The clean encoder has no view-dependent errors to lose.
  const auto clean = map_of(old, " --sim-encoder clean");
  ASSERT_EQ(clean.exit_code, 0) << clean.output;
  EXPECT_EQ(clean.output.find(warning), std::string::npos) << clean.output;
}

}  // namespace
}  // namespace slamvdb::testing
