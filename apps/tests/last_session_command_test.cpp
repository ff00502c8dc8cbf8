// A voxel's last-observed session through the commands (issue 23): two SIMULATED drives' files
// over partly the same ground (Monday: columns 0-19, Friday: 5-24, later), merged by `merge`;
// `query --at` and `classify -o X.csv` name the newest session that saw each voxel, and
// `export --last-session` keeps what one drive saw last.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;
constexpr double kLastSessionCliVoxel = 0.5;

// A drive's map: one submap, a 20 x 10 patch of ground from world column `start`, t0..t0 + 5 s.
SemanticMap last_session_cli_drive(int start, double t0) {
  MapParams params;
  params.occupancy.voxel_size = kLastSessionCliVoxel;
  params.semantic = {16, EmbeddingPrecision::kFloat16};
  SemanticMap map(params, {.model_id = "simulated-clip-test", .source = "SIMULATED patch"});
  VoxelMap voxels(params);
  std::vector<float> e(16, 0.0f);
  e[0] = 1.0f;
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 10; ++y) {
      voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
      voxels.semantics().set({x, y, 0}, e.data(), 3);
    }
  SubmapInfo info;
  info.T_world_submap.translation() = Vec3d(start * kLastSessionCliVoxel, 0, 0);
  info.time_range = {t0, t0 + 5};
  map.add_finished_submap(info, std::move(voxels));
  return map;
}

class LastSessionCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("slamvdb_last_session_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    save_map(dir_ / "monday.svdb", last_session_cli_drive(0, 10.0));
    save_map(dir_ / "friday.svdb", last_session_cli_drive(5, 1000.0));
    const CommandResult merged = run_cli("merge " + q("monday.svdb") + " " + q("friday.svdb") + " -o " + q("site.svdb"));
    ASSERT_EQ(merged.exit_code, 0) << merged.output;
    ASSERT_EQ(read_map_summary(dir_ / "site.svdb").submaps.size(), 1u) << merged.output;
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string q(const std::string& name) const { return shell_quote((dir_ / name).string()); }
  std::string slurp(const std::string& name) const {
    std::ifstream in(dir_ / name, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  fs::path dir_;
};

// The last field of each data row of a CSV, counted.
std::map<std::string, std::size_t> last_fields(const std::string& csv) {
  std::map<std::string, std::size_t> out;
  std::istringstream rows(csv);
  std::string row;
  std::getline(rows, row);
  while (std::getline(rows, row)) ++out[row.substr(row.rfind(',') + 1)];
  return out;
}

TEST_F(LastSessionCommand, QueryAndClassifyNameTheNewestSessionPerVoxel) {
  // Column 2 only Monday saw, column 10 both, column 22 only Friday.
  const CommandResult r = run_cli("query " + q("site.svdb") + " --at 1.25,2.25,0.25 --at 5.25,2.25,0.25 --at "
                                  "11.25,2.25,0.25 -o " + q("at.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string at = slurp("at.csv");
  const std::string header = at.substr(0, at.find('\n'));
  EXPECT_EQ(header.substr(header.rfind(',')), ",last_session") << at;
  EXPECT_EQ(last_fields(at), (std::map<std::string, std::size_t>{{"friday", 2}, {"monday", 1}})) << at;

  QuerySet set;
  set.model_id = "simulated-clip-test";
  set.names = {"smooth", "rough"};
  set.vectors = QueryMatrix::Identity(2, 16);
  save_query_set(dir_ / "q.json", set);
  const CommandResult c = run_cli("classify " + q("site.svdb") + " --queries " + q("q.json") + " -o " + q("c.csv"));
  ASSERT_EQ(c.exit_code, 0) << c.output;
  EXPECT_EQ(last_fields(slurp("c.csv")), (std::map<std::string, std::size_t>{{"friday", 200}, {"monday", 50}}));
}

TEST_F(LastSessionCommand, ExportKeepsWhatOneDriveSawLast) {
  const CommandResult m = run_cli("export " + q("site.svdb") + " --last-session monday -o " + q("m.csv"));
  ASSERT_EQ(m.exit_code, 0) << m.output;
  EXPECT_NE(m.output.find("--last-session monday: 50 of 250 semantic voxels"), std::string::npos) << m.output;
  EXPECT_EQ(last_fields(slurp("m.csv")), (std::map<std::string, std::size_t>{{"3", 50}}))
      << "Monday's own five columns (x,y,z,count: 3 views each), no voxel Friday saw";
  const CommandResult bad = run_cli("export " + q("site.svdb") + " --last-session sunday -o " + q("x.csv"));
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("no session 'sunday' in the map; its sessions are 'monday', 'friday'"), std::string::npos)
      << bad.output;
  EXPECT_FALSE(fs::exists(dir_ / "x.csv"));
}

}  // namespace
}  // namespace slamvdb::testing
