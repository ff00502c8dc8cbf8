// `slamvdb align` end to end on two SIMULATED maps (testing/simulated_sessions.hpp): the same
// terrain seen by two sessions in different world frames, written as map files; the command
// recovers the pose, writes OTHER with its anchors moved into BASE's world (voxels untouched),
// refuses maps that do not overlap or cannot share a world (exit 1, the reason), and checks
// --initial before any work (exit 2).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/simulated_sessions.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;

// The other session: turned 37 degrees, moved, 1.35 m higher (voxel lattices 0.10 m apart in z).
Pose align_command_other_world() { return make_align_test_pose(37.0, Vec3d(40.0, -25.0, 1.35)); }

// Where the other maps' drives end (metres of route). The sanitizer run (SLAMVDB_TEST_SCALE) writes
// one 50 m submap of each instead of two: the command's time is in verifying candidate pairs, 3 per
// place of the other map, and under ASan each test took 40 s. What the command is checked for here
// (the pose, the moved anchors, the refusal and its reason) holds on one submap as on two.
int align_command_other_end() { return test_size(100, 70); }
int align_command_unrelated_end() { return test_size(100, 50); }

class AlignCommand : public ::testing::Test {
 public:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("slamvdb_align_command_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const AlignTestWorld world = make_align_world(7, 100);
    save_map(base(), make_align_session_map(make_align_session(world, Pose::Identity(), 0, 100),
                                            "SIMULATED terrain seed 7, session A"));
    save_map(other(), make_align_session_map(make_align_session(world, align_command_other_world(), 20, align_command_other_end()),
                                             "SIMULATED terrain seed 7, session B"));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static fs::path file(const std::string& name) { return dir_ / name; }
  static fs::path base() { return dir_ / "base.svdb"; }
  static fs::path other() { return dir_ / "other.svdb"; }
  static std::string q(const fs::path& p) { return shell_quote(p.string()); }

 private:
  static inline fs::path dir_;
};

// One finished, empty submap (id 0): a map file with the parameters under test.
SubmapInfo align_command_empty_submap() {
  SubmapInfo info;
  info.finished = true;
  return info;
}

Pose pose_from_json(const nlohmann::json& j) {
  Pose T = Pose::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = j.at("matrix").at(r).at(c).get<double>();
  return T;
}

TEST_F(AlignCommand, RecoversThePoseAndWritesTheOtherMapInTheBasesWorld) {
  const fs::path out = file("other_in_base.svdb"), report = file("report.json");
  const CommandResult r = run_cli("align " + q(base()) + " " + q(other()) + " -o " + q(out) + " --json " + q(report), 300);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::printf("%s", r.output.c_str());
  EXPECT_NE(r.output.find("T_base_other"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("uncertainty"), std::string::npos) << r.output;

  nlohmann::json j;
  std::ifstream(report) >> j;
  ASSERT_TRUE(j.at("aligned").get<bool>()) << j.dump(2);
  const Pose expected = align_command_other_world().inverse();  // T_base_other
  const Pose found = pose_from_json(j.at("T_base_other"));
  const double angle = Eigen::AngleAxisd((expected.inverse() * found).linear()).angle() * 180.0 / M_PI;
  EXPECT_LT(angle, 0.5);
  EXPECT_GE(j.at("consistent_pairs").get<int>(), 3);
  EXPECT_GT(j.at("uncertainty").at("translation_m").get<double>(), 0.0);
  EXPECT_GT(j.at("refined").at("overlap").get<double>(), 0.8);
  EXPECT_NEAR(j.at("T_base_other").at("yaw_deg").get<double>(), -37.0, 0.5);

  // Every anchor of the written map is where the true transform puts the input's, within the
  // issue's 0.10 m, and far from where it was; the voxels are the input's (no re-integration).
  const MapFileSummary before = read_map_summary(other()), after = read_map_summary(out);
  ASSERT_EQ(after.submaps.size(), before.submaps.size());
  EXPECT_EQ(after.occupied_voxels, before.occupied_voxels);
  EXPECT_EQ(after.info.source, before.info.source);
  // OTHER's session is kept (named after OTHER's file, where it was made), every submap in it.
  ASSERT_EQ(after.info.sessions.size(), 1u);
  EXPECT_EQ(after.info.sessions[0].name, "other");
  EXPECT_EQ(after.info.sessions[0].source, before.info.sessions[0].source);
  for (const SubmapSummary& s : after.submaps) EXPECT_EQ(s.info.session, after.info.sessions[0].id);
  double worst = 0.0;
  for (std::size_t i = 0; i < before.submaps.size(); ++i) {
    ASSERT_EQ(after.submaps[i].info.id, before.submaps[i].info.id);
    const Pose& was = before.submaps[i].info.T_world_submap;
    const Pose& now = after.submaps[i].info.T_world_submap;
    worst = std::max(worst, (now.translation() - (expected * was).translation()).norm());
    EXPECT_GT((now.translation() - was.translation()).norm(), 10.0) << "submap " << before.submaps[i].info.id;
    EXPECT_LT(Eigen::AngleAxisd((expected * was).linear().transpose() * now.linear()).angle() * 180.0 / M_PI, 0.5);
  }
  EXPECT_LT(worst, 0.10);
  std::printf("SIMULATED align: worst anchor error %.3f m, rotation error %.3f deg, %d consistent pairs\n", worst,
              angle, j.at("consistent_pairs").get<int>());
}

TEST_F(AlignCommand, RefusesMapsThatDoNotOverlapWithTheReason) {
  // A drive through other terrain (seed 8), as in AlignSessions.RefusesMapsThatDoNotOverlap.
  const AlignTestWorld world_b = make_align_world(8, align_command_unrelated_end());
  const fs::path a = base(), b = file("seed8.svdb"), out = file("never.svdb");
  save_map(b, make_align_session_map(make_align_session(world_b, make_align_test_pose(-20.0, Vec3d(5, 5, 0)), 0, align_command_unrelated_end()),
                                     "SIMULATED terrain seed 8"));
  const CommandResult r = run_cli("align " + q(a) + " " + q(b) + " -o " + q(out), 300);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cannot align"), std::string::npos) << r.output;
  // The reason, whichever rule refused (here too few verified pairs agree; with the library's own
  // voxel order, the refined overlap): the refusal line of the report and the error.
  EXPECT_NE(r.output.find("refused      "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("not written"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out)) << "a refused alignment writes no map";
}

TEST_F(AlignCommand, RefusesMapsThatCannotShareAWorldBeforeLoadingThem) {
  // Another voxel size, then another ontology: exit 1 naming both values.
  MapParams params;
  params.occupancy.voxel_size = 0.5;
  SemanticMap coarse(params, MapInfo{.source = "SIMULATED"});
  coarse.add_finished_submap(align_command_empty_submap(), VoxelMap(params));
  save_map(file("coarse.svdb"), coarse);
  const CommandResult r = run_cli("align " + q(base()) + " " + q(file("coarse.svdb")) + " -o " + q(file("x.svdb")));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("different voxel sizes: base 0.25 m, other 0.5 m"), std::string::npos) << r.output;

  SemanticMap other_ontology(MapParams{}, MapInfo{.ontology = "rellis3d-coarse", .source = "SIMULATED"});
  other_ontology.add_finished_submap(align_command_empty_submap(), VoxelMap(MapParams{}));
  save_map(file("coarse_ontology.svdb"), other_ontology);
  const CommandResult o = run_cli("align " + q(base()) + " " + q(file("coarse_ontology.svdb")) + " -o " + q(file("x.svdb")));
  EXPECT_EQ(o.exit_code, 1) << o.output;
  EXPECT_NE(o.output.find("different ontologies: base 'rellis3d', other 'rellis3d-coarse'"), std::string::npos)
      << o.output;
  EXPECT_FALSE(fs::exists(file("x.svdb")));
}

TEST_F(AlignCommand, ABadInitialPoseIsAUsageError) {
  for (const std::string bad : {"1,2,3", "1,2,3,4,5", "1,2,nan,4", "x,y,z,yaw"}) {
    const CommandResult r =
        run_cli("align " + q(base()) + " " + q(other()) + " -o " + q(file("y.svdb")) + " --initial=" + bad);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.output;
    EXPECT_NE(r.output.find("--initial '" + bad + "'"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(file("y.svdb")));
  }
}

}  // namespace
}  // namespace slamvdb::testing
