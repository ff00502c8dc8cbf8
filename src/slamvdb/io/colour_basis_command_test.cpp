// PCA colours are stable between maps of the same embedding space: `map` saves the basis it draws
// in, a later map adopts an earlier one's with --colour-basis, and `export` draws in the saved
// basis (or in another map's with --colour-basis), so the same embedding gets the same colour.
#include <gtest/gtest.h>

#include <fstream>

#include "slamvdb/io/map_export.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;
using testing::shell_quote;
const auto colour_cli = [](const std::string& args) { return testing::run_cli(args); };

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(ColourBasisCommand, MapsOfOneSpaceShareTheirColours) {
  testing::TempDir tmp;
  const auto q = [&](const char* name) { return shell_quote((tmp.path / name).string()); };
  // A SIMULATED 15 m drive with small images and scans: semantics in a second.
  ASSERT_EQ(colour_cli("synth " + q("seq") + " --length 15 --image-size 160x100 --lidar-columns 256").exit_code, 0);
  const std::string map = "map " + q("seq") + " --dim 8 --feature-size 80x50 ";
  ASSERT_EQ(colour_cli(map + "-o " + q("a.svdb")).exit_code, 0);
  // b and c: the same part of the drive; b adopts a's basis, c fits its own.
  CommandResult r = colour_cli(map + "--max-scans 10 -o " + q("b.svdb") + " --colour-basis " + q("a.svdb"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_EQ(colour_cli(map + "--max-scans 10 -o " + q("c.svdb")).exit_code, 0);

  const SemanticMap a = load_map(tmp.path / "a.svdb"), b = load_map(tmp.path / "b.svdb"),
                    c = load_map(tmp.path / "c.svdb");
  ASSERT_GT(a.num_index_cells(), 0u);
  ASSERT_GT(c.num_index_cells(), 0u);
  ASSERT_TRUE(a.info().colour_basis && b.info().colour_basis && c.info().colour_basis);
  EXPECT_EQ(b.info().colour_basis->components, a.info().colour_basis->components);
  EXPECT_EQ(b.info().colour_basis->mean, a.info().colour_basis->mean);
  EXPECT_NE(c.info().colour_basis->mean, a.info().colour_basis->mean);  // fitted on other data

  // Export draws in the saved basis: every semantic voxel of b coloured by a's basis.
  const ColourBasis& basis_a = *a.info().colour_basis;
  const auto drawn = colour_by_pca(b);
  const auto expected = colour_occupied_voxels(b, [&](const float* e) { return basis_a.colour(e); });
  ASSERT_EQ(drawn.size(), expected.size());
  for (std::size_t i = 0; i < drawn.size(); ++i) EXPECT_EQ(drawn[i].rgb, expected[i].rgb) << i;

  // c exported in a's basis is b's picture to the byte; in its own basis it is not.
  ASSERT_EQ(colour_cli("export " + q("b.svdb") + " -o " + q("b.ply")).exit_code, 0);
  r = colour_cli("export " + q("c.svdb") + " -o " + q("c_in_a.ply") + " --colour-basis " + q("a.svdb"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_EQ(colour_cli("export " + q("c.svdb") + " -o " + q("c.ply")).exit_code, 0);
  EXPECT_EQ(bytes_of(tmp.path / "c_in_a.ply"), bytes_of(tmp.path / "b.ply"));
  EXPECT_NE(bytes_of(tmp.path / "c.ply"), bytes_of(tmp.path / "b.ply"));

  // A basis of another dimension is refused before mapping; with --queries it makes no sense.
  r = colour_cli("map " + q("seq") + " --dim 16 -o " + q("d.svdb") + " --colour-basis " + q("a.svdb"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("8-d, this map's are 16-d"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "d.svdb"));
  r = colour_cli("export " + q("c.svdb") + " -o " + q("x.ply") + " --colour-basis " + q("a.svdb") + " --queries " + q("a.svdb"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

}  // namespace
}  // namespace slamvdb
