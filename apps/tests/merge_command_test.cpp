// `slamvdb merge` and the sessions `slamvdb info` lists, end to end on map files of the store
// tests' synthetic maps (testing/map_store_fixtures.hpp): every input's submaps and view counts
// in the output, one session per input named after its file; incompatible inputs refused
// (exit 1, naming the difference, nothing written); fewer than two inputs a usage error.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "slamvdb/sessions/map_merge.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;

class MergeCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("slamvdb_merge_command_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    save_map(dir_ / "monday.svdb", make_map(EmbeddingPrecision::kFloat16, 16, 1));
    save_map(dir_ / "friday.svdb", make_map(EmbeddingPrecision::kFloat16, 16, 2));
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string q(const std::string& name) const { return shell_quote((dir_ / name).string()); }
  fs::path dir_;
};

uint64_t merge_command_observations(const fs::path& path) { return sessions::map_contents(load_map(path)).observations; }

TEST_F(MergeCommand, WritesEverySessionsSubmapsAndLosesNoCount) {
  const CommandResult r = run_cli("merge " + q("monday.svdb") + " " + q("friday.svdb") + " -o " + q("site.svdb") +
                                  " --json " + q("merge.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const MapFileSummary a = read_map_summary(dir_ / "monday.svdb"), b = read_map_summary(dir_ / "friday.svdb");
  const MapFileSummary site = read_map_summary(dir_ / "site.svdb");
  EXPECT_EQ(site.submaps.size(), a.submaps.size() + b.submaps.size());
  EXPECT_EQ(site.known_voxels, a.known_voxels + b.known_voxels);
  EXPECT_EQ(site.semantic_voxels, a.semantic_voxels + b.semantic_voxels);
  EXPECT_EQ(merge_command_observations(dir_ / "site.svdb"),
            merge_command_observations(dir_ / "monday.svdb") + merge_command_observations(dir_ / "friday.svdb"));
  ASSERT_EQ(site.info.sessions.size(), 2u);
  EXPECT_EQ(site.info.sessions[0].name, "monday");
  EXPECT_EQ(site.info.sessions[1].name, "friday");
  EXPECT_EQ(site.info.sessions[1].source, b.info.source);
  for (std::size_t i = 0; i < site.submaps.size(); ++i)
    EXPECT_EQ(site.submaps[i].info.session, i < a.submaps.size() ? 0 : 1);
  nlohmann::json j;
  std::ifstream(dir_ / "merge.json") >> j;
  EXPECT_EQ(j.at("merged").at("submaps").get<std::size_t>(), site.submaps.size());
  EXPECT_EQ(j.at("merged").at("observations").get<uint64_t>(), merge_command_observations(dir_ / "site.svdb"));

  // info lists the sessions: text and JSON (name, source, time range, submaps).
  const CommandResult text = run_cli("info " + q("site.svdb"));
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_NE(text.output.find("sessions   2"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("id 1    friday  source " + b.info.source + "  time 10.000..24.500 s  2 submaps"),
            std::string::npos) << text.output;
  const CommandResult json = run_cli("info --json " + q("site.svdb"));
  ASSERT_EQ(json.exit_code, 0) << json.output;
  const nlohmann::json info = nlohmann::json::parse(json.output);
  ASSERT_EQ(info.at("sessions").size(), 2u);
  EXPECT_EQ(info.at("sessions").at(0).at("name"), "monday");
  EXPECT_EQ(info.at("sessions").at(0).at("source"), a.info.source);
  EXPECT_EQ(info.at("sessions").at(0).at("submaps"), 2);
  EXPECT_EQ(info.at("sessions").at(0).at("time_range"), nlohmann::json({10.0, 24.5}));
  EXPECT_EQ(info.at("submaps").at(3).at("session"), 1);
}

TEST_F(MergeCommand, RefusesMapsThatCannotShareAWorldAndWritesNothing) {
  MapParams params = make_map(EmbeddingPrecision::kFloat16, 16, 3).params();
  params.occupancy.voxel_size = 0.5;
  save_map(dir_ / "coarse.svdb", SemanticMap(params, {.model_id = "simulated-clip-test", .source = "coarse"}));
  const CommandResult r = run_cli("merge " + q("monday.svdb") + " " + q("coarse.svdb") + " -o " + q("site.svdb"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("different voxel sizes: base 0.2 m, other 0.5 m"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("not written"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "site.svdb"));
}

TEST_F(MergeCommand, TheSameDriveTwiceMergesIntoOneSubmapPerPlaceAndCountsWhatSaturates) {
  fs::copy_file(dir_ / "monday.svdb", dir_ / "again.svdb");
  const CommandResult r = run_cli("merge " + q("monday.svdb") + " " + q("again.svdb") + " -o " + q("site.svdb") +
                                  " --json " + q("merge.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("overlap    submap 2 (session 1) merged into submap 0 (session 0): 100.0% overlap"),
            std::string::npos) << r.output;
  const MapFileSummary one = read_map_summary(dir_ / "monday.svdb"), site = read_map_summary(dir_ / "site.svdb");
  EXPECT_EQ(site.submaps.size(), one.submaps.size()) << "each place once";
  EXPECT_EQ(site.occupied_voxels, one.occupied_voxels);
  EXPECT_EQ(site.info.sessions.size(), 2u) << "both drives listed";
  // Each submap has a voxel seen UINT32_MAX times: twice that does not fit, and is reported.
  const uint64_t once = merge_command_observations(dir_ / "monday.svdb");
  EXPECT_EQ(merge_command_observations(dir_ / "site.svdb"), 2 * once - 2 * uint64_t{UINT32_MAX});
  EXPECT_NE(r.output.find(fmt::format("{} dropped where merged voxels became free or counts saturated",
                                      2 * uint64_t{UINT32_MAX})),
            std::string::npos) << r.output;
  nlohmann::json j;
  std::ifstream(dir_ / "merge.json") >> j;
  ASSERT_EQ(j.at("overlap_merges").size(), 2u);
  EXPECT_EQ(j.at("overlap_merges").at(1).at("observations_clipped").get<uint64_t>(), uint64_t{UINT32_MAX});
  const CommandResult apart = run_cli("merge " + q("monday.svdb") + " " + q("again.svdb") + " -o " + q("apart.svdb") +
                                      " --keep-sessions-apart");
  ASSERT_EQ(apart.exit_code, 0) << apart.output;
  EXPECT_EQ(read_map_summary(dir_ / "apart.svdb").submaps.size(), 2 * one.submaps.size());
  EXPECT_EQ(merge_command_observations(dir_ / "apart.svdb"), 2 * once);
}

TEST_F(MergeCommand, OneInputIsAUsageError) {
  const CommandResult r = run_cli("merge " + q("monday.svdb") + " -o " + q("site.svdb"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "site.svdb"));
}

}  // namespace
}  // namespace slamvdb::testing
