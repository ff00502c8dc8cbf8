// GET /api/nav-grid and `slamvdb classify --bbox/--near ... --grid PREFIX`: the same grid of the
// same region (both build it through query/nav_grid.hpp and encode it through
// io/nav_grid_files.hpp), cell for cell; the region's grid is the whole map's grid there; refusals
// name the parameter.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

// A binary PGM (P5, maxval 255) as costs, row-major from the south (as NavGrid and the JSON
// answer's `cost`: 255 is unknown, -1).
struct PgmGrid {
  int width = 0, height = 0;
  std::vector<int> cost;
};
PgmGrid parse_nav_pgm(const std::string& bytes) {
  std::istringstream in(bytes);
  std::string magic;
  int maxval = 0;
  PgmGrid g;
  in >> magic >> g.width >> g.height >> maxval;
  in.get();  // the one whitespace before the pixels
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(maxval, 255);
  const std::string pixels = bytes.substr(static_cast<std::size_t>(in.tellg()));
  EXPECT_EQ(pixels.size(), static_cast<std::size_t>(g.width) * g.height);
  g.cost.assign(pixels.size(), 0);
  for (int row = 0; row < g.height; ++row)  // image rows run north to south
    for (int col = 0; col < g.width; ++col) {
      const auto v = static_cast<uint8_t>(pixels[static_cast<std::size_t>(g.height - 1 - row) * g.width + col]);
      g.cost[static_cast<std::size_t>(row) * g.width + col] = v == 255 ? -1 : v;
    }
  return g;
}

std::string nav_get(testing::ServedMap& s, const std::string& path, int expected_status, const std::string& type) {
  const auto res = s.client.Get(path);
  EXPECT_TRUE(res) << "no answer; server log:\n" << s.log();
  if (!res) return {};
  EXPECT_EQ(res->status, expected_status) << path << "\n" << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), type) << path;
  return res->body;
}

// The files `classify ... --grid PREFIX ARGS` writes: pgm, png, yaml.
struct CliGrid {
  std::string pgm, png, yaml;
};
CliGrid classify_grid(const testing::ServedMap& s, const std::string& args) {
  const auto prefix = s.f.tmp.path / "grid";
  const auto r = run_command(s.f.cli("classify " + shell_quote(s.f.map.string()) + " --queries " +
                                     shell_quote(s.f.queries.string()) + " --ignore-model-id " + args + " --grid " +
                                     shell_quote(prefix.string())));
  EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  return {testing::read_text_file(prefix.string() + ".pgm"), testing::read_text_file(prefix.string() + ".png"),
          testing::read_text_file(prefix.string() + ".yaml")};
}

TEST(ServeNavGrid, TheRegionsGridEqualsClassifyGridCellForCellAndIsTheWholeMapsGridThere) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const CliGrid whole_cli = classify_grid(s, "");
  const PgmGrid whole = parse_nav_pgm(whole_cli.pgm);
  const nlohmann::json whole_json = nlohmann::json::parse(nav_get(s, "/api/nav-grid?bbox=-10,-10,-10,10,10,10", 200, "application/json"));
  ASSERT_EQ(whole_json.at("width").get<int>(), whole.width);
  ASSERT_EQ(whole_json.at("height").get<int>(), whole.height);
  const double res = whole_json.at("resolution").get<double>();
  const double wx0 = whole_json.at("origin")[0].get<double>(), wy0 = whole_json.at("origin")[1].get<double>();

  for (const auto& [query, cli_args] : std::vector<std::pair<std::string, std::string>>{
           {"bbox=-2.1,-1.3,-10,1.6,2.2,10", "--bbox=-2.1,-1.3,-10,1.6,2.2,10"},
           {"near=0.5,-0.5&radius=1.7&min_confidence=0.3&robot_height=1.2",
            "--near 0.5,-0.5 --radius 1.7 --min-confidence 0.3 --robot-height 1.2"}}) {
    const CliGrid cli = classify_grid(s, cli_args);
    const std::string base = "/api/nav-grid?" + query;
    // The files' bytes: the PGM and the PNG as classify writes them, the YAML but for its image name.
    EXPECT_EQ(nav_get(s, base + "&format=pgm", 200, "image/x-portable-graymap"), cli.pgm) << query;
    EXPECT_EQ(nav_get(s, base + "&format=png", 200, "image/png"), cli.png) << query;
    std::string yaml = nav_get(s, base + "&format=yaml", 200, "application/yaml");
    const auto image = yaml.find("nav-grid.pgm");
    ASSERT_NE(image, std::string::npos) << yaml;
    yaml.replace(image, std::string("nav-grid.pgm").size(), "grid.pgm");
    EXPECT_EQ(yaml, cli.yaml) << query;
    // The JSON's costs, cell for cell, against the CLI's PGM.
    const nlohmann::json answer = nlohmann::json::parse(nav_get(s, base, 200, "application/json"));
    const PgmGrid grid = parse_nav_pgm(cli.pgm);
    ASSERT_EQ(answer.at("width").get<int>(), grid.width) << query;
    ASSERT_EQ(answer.at("height").get<int>(), grid.height) << query;
    EXPECT_EQ(answer.at("cost").get<std::vector<int>>(), grid.cost) << query;
    EXPECT_EQ(answer.at("class_costs").at("smooth").get<int>(), 0);
    EXPECT_EQ(answer.at("class_costs").at("rough").get<int>(), 30);
    // A part of the map: smaller than the whole grid, both classes' costs in it (x < 0 and x >= 0).
    EXPECT_LT(static_cast<std::size_t>(grid.width) * grid.height, whole.cost.size()) << query;
    const auto& cost = answer.at("cost");
    EXPECT_NE(std::find(cost.begin(), cost.end(), 0), cost.end()) << query;
    EXPECT_NE(std::find(cost.begin(), cost.end(), 30), cost.end()) << query;
    // The whole map's grid at the same world cells (a flat map: no obstacle cut by the region).
    const double ox = answer.at("origin")[0].get<double>(), oy = answer.at("origin")[1].get<double>();
    const int dx = static_cast<int>(std::lround((ox - wx0) / res)), dy = static_cast<int>(std::lround((oy - wy0) / res));
    ASSERT_GE(dx, 0);
    ASSERT_GE(dy, 0);
    if (query.rfind("bbox", 0) == 0) {  // the near query has a confidence threshold the whole grid has not
      for (int row = 0; row < grid.height; ++row)
        for (int col = 0; col < grid.width; ++col) {
          ASSERT_EQ(grid.cost[static_cast<std::size_t>(row) * grid.width + col],
                    whole.cost[static_cast<std::size_t>(row + dy) * whole.width + col + dx])
              << query << " cell " << col << "," << row;
        }
    }
  }

  // Refusals: 400 naming the parameter, 404 for a region without occupied cells.
  for (const auto& [query, status, field] : std::vector<std::tuple<std::string, int, std::string>>{
           {"", 400, "bbox"},
           {"?bbox=0,0,0,1,1", 400, "bbox"},
           {"?near=0,0", 400, "radius"},
           {"?bbox=-1,-1,-1,1,1,1&resolution=0.37", 400, "resolution"},
           {"?bbox=-1,-1,-1,1,1,1&format=gif", 400, "format"},
           {"?bbox=-1,-1,-1,1,1,1&robot_height=0", 400, "robot_height"},
           {"?bbox=-1,-1,-1,1,1,1&min_confidence=-1", 400, "min_confidence"},
           {"?bbox=-1,-1,-1,1,1,1&res=1", 400, "res"},
           {"?bbox=100,100,0,110,110,1", 404, "bbox"}}) {
    const nlohmann::json refusal = nlohmann::json::parse(nav_get(s, "/api/nav-grid" + query, status, "application/json"));
    EXPECT_EQ(refusal.at("error").at("field"), field) << query;
  }
  // A coarser grid (twice the map's cell): the CLI's --grid-resolution, byte for byte, and each
  // cell the worst of its 2 x 2 cells of the fine grid (lethal first, else the highest known cost).
  {
    const std::string box = "-2.1,-1.3,-10,1.6,2.2,10";
    const CliGrid coarse_cli = classify_grid(s, fmt::format("--bbox={} --grid-resolution {}", box, 2 * res));
    const std::string coarse_pgm =
        nav_get(s, fmt::format("/api/nav-grid?bbox={}&resolution={}&format=pgm", box, 2 * res), 200, "image/x-portable-graymap");
    EXPECT_EQ(coarse_pgm, coarse_cli.pgm);
    const PgmGrid coarse = parse_nav_pgm(coarse_pgm), fine = parse_nav_pgm(classify_grid(s, "--bbox=" + box).pgm);
    ASSERT_EQ(coarse.width, (fine.width + 1) / 2);
    ASSERT_EQ(coarse.height, (fine.height + 1) / 2);
    for (int row = 0; row < coarse.height; ++row)
      for (int col = 0; col < coarse.width; ++col) {
        int worst = -1;
        for (int r = 2 * row; r < std::min(2 * row + 2, fine.height); ++r)
          for (int c = 2 * col; c < std::min(2 * col + 2, fine.width); ++c)
            worst = std::max(worst, fine.cost[static_cast<std::size_t>(r) * fine.width + c]);
        ASSERT_EQ(coarse.cost[static_cast<std::size_t>(row) * coarse.width + col], worst) << col << "," << row;
      }
  }
  // The map's own resolution is accepted.
  nav_get(s, fmt::format("/api/nav-grid?bbox=-1,-1,-1,1,1,1&resolution={}", res), 200, "application/json");
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

TEST(ServeNavGrid, ARegionOverMaxCellsIsRefusedWith413) {
  testing::TwoClassMap f;
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                 "--ignore-model-id", "--max-cells", "20"},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  const auto over = client.Get("/api/nav-grid?bbox=-3,-3,-1,3,3,1");
  ASSERT_TRUE(over);
  EXPECT_EQ(over->status, 413) << over->body;
  const std::string message = nlohmann::json::parse(over->body).at("error").at("message").get<std::string>();
  EXPECT_NE(message.find("at most 20"), std::string::npos) << message;
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

}  // namespace
}  // namespace slamvdb
