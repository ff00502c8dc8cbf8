// `--session NAME[,NAME]` on export, query and classify, end to end: a site map merged from two
// sessions' files (the store tests' synthetic maps, which do not overlap enough to merge) answers
// for one session as that session's own file does; an unknown name is refused (exit 1) naming the
// sessions the file has, and nothing is written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/sessions/map_merge.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;

class SessionOption : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("slamvdb_session_option_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    save_map(dir_ / "monday.svdb", make_map(EmbeddingPrecision::kFloat16, 16, 1));
    save_map(dir_ / "friday.svdb", make_map(EmbeddingPrecision::kFloat16, 16, 2));
    const CommandResult merged = run_cli("merge " + q("monday.svdb") + " " + q("friday.svdb") + " -o " + q("site.svdb"));
    ASSERT_EQ(merged.exit_code, 0) << merged.output;
    ASSERT_EQ(read_map_summary(dir_ / "site.svdb").submaps.size(), 4u) << "nothing merged: the sessions stay apart";
    QuerySet set;  // one-hot classes in the maps' space
    set.model_id = "simulated-clip-test";
    set.names = {"smooth", "rough", "bumpy", "obstacle", "active", "void"};
    set.vectors = QueryMatrix::Identity(6, 16);
    set.void_classes = {5};
    save_query_set(dir_ / "q.json", set);
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

TEST_F(SessionOption, ExportWritesOnlyTheNamedSessionsVoxels) {
  const std::vector<std::pair<std::string, std::string>> runs = {{"friday.svdb", "friday.csv"},
                                                                 {"site.svdb --session friday", "site_f.csv"},
                                                                 {"site.svdb", "site.csv"},
                                                                 {"site.svdb --session friday,monday", "site_fm.csv"}};
  for (const auto& [args, out] : runs) {
    const CommandResult r = run_cli("export " + q("") + args + " -o " + q(out));
    ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  }
  EXPECT_EQ(slurp("site_f.csv"), slurp("friday.csv")) << "friday's voxels and counts, no other";
  EXPECT_EQ(slurp("site_fm.csv"), slurp("site.csv")) << "both sessions: the whole map";
  EXPECT_NE(slurp("site.csv"), slurp("friday.csv"));
}

TEST_F(SessionOption, ClassifyAndQueryAnswerForTheNamedSessionsOnly) {
  const std::vector<std::pair<std::string, std::string>> runs = {{"friday.svdb", "friday.csv"},
                                                                 {"site.svdb --session friday", "site_f.csv"}};
  for (const auto& [args, out] : runs) {
    const CommandResult r = run_cli("classify " + q("") + args + " --queries " + q("q.json") + " -o " + q(out));
    ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  }
  EXPECT_EQ(slurp("site_f.csv"), slurp("friday.csv"));
  // A semantic voxel of monday's (its first row in monday's export) is found with monday only.
  ASSERT_EQ(run_cli("export " + q("monday.svdb") + " -o " + q("monday.csv")).exit_code, 0);
  std::istringstream rows(slurp("monday.csv"));
  std::string header, row;
  std::getline(rows, header), std::getline(rows, row);
  const std::string point = row.substr(0, row.rfind(','));  // x,y,z
  const auto found = [&](const std::string& session) {
    const CommandResult r =
        run_cli("query " + q("site.svdb") + " --session " + session + " --at " + point + " -o " + q("at.csv"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("--session " + session + ": 2 of 4 submaps"), std::string::npos) << r.output;
    return r.output.find("1 points, 1 in a semantic voxel") != std::string::npos;
  };
  EXPECT_TRUE(found("monday"));
  EXPECT_FALSE(found("friday"));
}

TEST_F(SessionOption, AnUnknownSessionIsRefusedNamingTheKnownOnes) {
  const std::string known = "no session 'sunday' in the map; its sessions are 'monday', 'friday'";
  const CommandResult e = run_cli("export " + q("site.svdb") + " --session friday,sunday -o " + q("x.csv"));
  EXPECT_EQ(e.exit_code, 1) << e.output;
  EXPECT_NE(e.output.find(known), std::string::npos) << e.output;
  EXPECT_FALSE(fs::exists(dir_ / "x.csv"));
  const CommandResult c = run_cli("classify " + q("site.svdb") + " --session sunday --queries " + q("q.json"));
  EXPECT_EQ(c.exit_code, 1) << c.output;
  EXPECT_NE(c.output.find(known), std::string::npos) << c.output;
  const CommandResult a = run_cli("query " + q("monday.svdb") + " --session sunday --at 0,0,0");
  EXPECT_EQ(a.exit_code, 1) << a.output;
  EXPECT_NE(a.output.find("no session 'sunday' in the map; its sessions are 'monday'"), std::string::npos) << a.output;
}

}  // namespace
}  // namespace slamvdb::testing
