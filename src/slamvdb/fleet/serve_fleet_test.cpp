// `slamvdb serve --db URL` on a real PostgreSQL 15 + PostGIS server the test starts, served by a
// child `slamvdb serve` on an ephemeral loopback port: POST /api/query with a region answers the
// rows of `slamvdb query --db` on that region, GET /api/classes those of `classify --db`; a
// question without a region is refused (400 naming `region`); a stopped database is 503 JSON (the
// server lives on and answers again once the database is back); the database is checked before
// anything listens (exit 1), a map file with --db is a usage error (exit 2); a failed statement is
// 503 and a damaged payload 500 (typed errors, not message text); the semantic cell count follows
// a push made while serving.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <pqxx/pqxx>
#include <regex>
#include <sstream>
#include <thread>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/query/query_set.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/served_map.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;
using Rows = std::vector<std::vector<std::string>>;

// Two sessions of three 10 m ground patches 100 m apart (the second moved by (3, 4) m, so cells
// hold entries of both), and a query set of two classes in their space.
struct ServedFleet {
  slamvdb::testing::TempDir tmp;
  slamvdb::testing::PostgresServer& postgres = slamvdb::testing::shared_postgres_server();
  std::string url = postgres.url(slamvdb::testing::fresh_test_database(postgres));
  std::filesystem::path queries = tmp.path / "q.json";
  std::unique_ptr<slamvdb::testing::ServerProcess> server;

  // `serve_url_tail`: libpq URL parameters the server's connections get beyond the test's (`&...`);
  // `serve_args`: more options of `slamvdb serve`.
  explicit ServedFleet(const std::string& serve_url_tail = "", const std::vector<std::string>& serve_args = {}) {
    FleetDatabase fleet(url);
    Pose north = Pose::Identity();
    north.translation() = Vec3d(3, 4, 0);
    fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "monday"});
    fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "tuesday", .T_fleet_session = north});
    QuerySet q;
    q.model_id = "fleet-test-space";
    q.names = {"near-edge", "far-edge"};
    q.vectors = QueryMatrix::Zero(2, 4);
    q.vectors(0, 3) = q.vectors(1, 1) = 1;
    save_query_set(queries, q);
    std::vector<std::string> args{"serve", "--db", url + serve_url_tail, "--port", "0", "--queries", queries.string(), "--no-text"};
    args.insert(args.end(), serve_args.begin(), serve_args.end());
    server = std::make_unique<slamvdb::testing::ServerProcess>(SLAMVDB_CLI_PATH, args, (tmp.path / "serve.log").string());
  }
  std::string log() const { return slamvdb::testing::read_text_file(tmp.path / "serve.log"); }
  // `slamvdb COMMAND --db URL --queries Q ARGS -o out.csv`: the CSV rows without the header.
  Rows cli_rows(const std::string& command, const std::string& args) const {
    const auto out = tmp.path / "cli.csv";
    const auto r = run_command(shell_quote(SLAMVDB_CLI_PATH) + " " + command + " --db " + shell_quote(url) +
                               " --queries " + shell_quote(queries.string()) + " " + args + " -o " +
                               shell_quote(out.string()) + " 2>&1");
    EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
    std::string error;
    auto records = slamvdb::testing::read_csv_strict(slamvdb::testing::read_text_file(out), &error);
    EXPECT_TRUE(records && !records->empty()) << error;
    if (!records || records->empty()) return {};
    return {records->begin() + 1, records->end()};
  }
};

std::pair<int, nlohmann::json> post(httplib::Client& client, const std::string& path, const nlohmann::json& body) {
  const auto res = client.Post(path, body.dump(), "application/json");
  if (!res) return {0, {}};
  return {res->status, nlohmann::json::parse(res->body)};
}
std::pair<int, nlohmann::json> get(httplib::Client& client, const std::string& path) {
  const auto res = client.Get(path);
  if (!res) return {0, {}};
  return {res->status, nlohmann::json::parse(res->body)};
}

TEST(ServeFleet, QueryAndClassesEqualTheCliOnTheSameRegionAndARegionIsRequired) {
  ServedFleet f;
  ASSERT_GT(f.server->port(), 0) << f.server->output() << "\n" << f.log();
  httplib::Client client("127.0.0.1", f.server->port());
  struct Case {
    nlohmann::json region;
    std::string cli_args;
  };
  const std::vector<Case> cases = {
      {{{"bbox", {-5, -5, -1, 240, 20, 2}}}, "--bbox=-5,-5,-1,240,20,2"},
      {{{"near", {105, 7}}, {"radius", 6}}, "--near 105,7 --radius 6"},
  };
  for (const Case& c : cases) {
    const auto [status, answer] = post(client, "/api/query", {{"class", "far-edge"}, {"top_k", 9}, {"region", c.region}});
    ASSERT_EQ(status, 200) << answer.dump() << "\n" << f.log();
    EXPECT_EQ(answer.at("served_from"), "fleet");
    EXPECT_EQ(answer.at("count").get<std::size_t>(), 9u);
    EXPECT_EQ(slamvdb::testing::query_answer_rows(answer), f.cli_rows("query", "--class far-edge --top-k 9 " + c.cli_args))
        << c.cli_args;
  }
  // GET /api/classes: the rows of classify --db on the region (a fleet's CSV has no last_session).
  const auto [status, classes] = get(client, "/api/classes?bbox=95,-5,-1,140,20,2");
  ASSERT_EQ(status, 200) << classes.dump();
  EXPECT_EQ(classes.at("served_from"), "fleet");
  const Rows rows = slamvdb::testing::classes_answer_rows(classes);
  EXPECT_GT(rows.size(), 100u);
  EXPECT_EQ(rows, f.cli_rows("classify", "--bbox=95,-5,-1,140,20,2"));

  // No region: refused, naming it, before the database is asked.
  const auto [refused, error] = post(client, "/api/query", {{"class", "far-edge"}, {"top_k", 9}});
  EXPECT_EQ(refused, 400);
  EXPECT_EQ(error.at("error").at("field"), "region") << error.dump();
  EXPECT_NE(error.at("error").at("message").get<std::string>().find("required for a fleet map"), std::string::npos);
  // POST /api/at: the answers of query_points on the region pulled whole (monday's and tuesday's
  // patches overlap at the first point; the second is on no patch).
  const std::vector<Vec3d> points{{104.1, 5.1, 0.1}, {150, 5, 0.1}};
  const auto [at_status, at] = post(client, "/api/at", {{"points", {{104.1, 5.1, 0.1}, {150, 5, 0.1}}}});
  ASSERT_EQ(at_status, 200) << at.dump();
  FleetDatabase fleet(f.url);
  const std::vector<PointQuery> expected =
      query_points(fleet.pull_map({Eigen::AlignedBox3d(Vec3d(95, -5, -1), Vec3d(160, 20, 2)), {}}), points);
  ASSERT_EQ(at.at("results").size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(at.at("results")[i].at("found").get<bool>(), expected[i].found) << i;
    EXPECT_EQ(at.at("results")[i].at("count").get<uint32_t>(), expected[i].count) << i;
  }
  EXPECT_TRUE(expected[0].found);
  EXPECT_GT(expected[0].count, 0u);
  // GET /api/points needs a region on a fleet.
  EXPECT_EQ(get(client, "/api/points").second.at("error").at("field"), "bbox");
  EXPECT_EQ(client.Get("/api/points?bbox=95,-5,-1,140,20,2")->status, 200);
  // The catalog: both sessions, six submaps, anchors in the fleet frame.
  const auto [info_status, info] = get(client, "/api/info");
  ASSERT_EQ(info_status, 200) << info.dump();
  EXPECT_EQ(info.at("sessions").size(), 2u);
  ASSERT_EQ(info.at("submaps").size(), 6u);
  EXPECT_EQ(info.at("submaps")[3].at("session"), "tuesday");
  EXPECT_EQ(info.at("submaps")[3].at("translation"), nlohmann::json({3.0, 4.0, 0.0}));
}

TEST(ServeFleet, AStoppedDatabaseIs503AndTheServerAnswersAgainWhenItIsBack) {
  ServedFleet f;
  ASSERT_GT(f.server->port(), 0) << f.server->output() << "\n" << f.log();
  httplib::Client client("127.0.0.1", f.server->port());
  const nlohmann::json question = {{"class", "near-edge"}, {"top_k", 3}, {"region", {{"bbox", {-5, -5, -1, 20, 20, 2}}}}};
  ASSERT_EQ(post(client, "/api/query", question).first, 200) << f.log();
  f.postgres.stop();
  const auto [status, error] = post(client, "/api/query", question);
  const auto [classes_status, classes_error] = get(client, "/api/classes?bbox=-5,-5,-1,20,20,2");
  const auto [health, healthz] = get(client, "/healthz");
  f.postgres.start();
  EXPECT_EQ(status, 503) << error.dump();
  EXPECT_NE(error.at("error").at("message").get<std::string>().find("fleet database"), std::string::npos) << error.dump();
  EXPECT_EQ(classes_status, 503) << classes_error.dump();
  EXPECT_EQ(health, 200);  // the server itself is up
  EXPECT_TRUE(f.server->running()) << f.log();
  EXPECT_EQ(post(client, "/api/query", question).first, 200) << f.log();
}

// The database failing with its connection alive (a statement cut by lock_timeout while another
// client holds the table) is 503 like a database that is gone: asking later may succeed. A payload
// damaged in the database is 500 with the reason: asking again gives the same. Told apart by the
// fleet part's error types (FleetDatabaseError, FleetDataError), never by a message's words.
TEST(ServeFleet, AFailedStatementIs503AndADamagedPayloadIs500) {
  ServedFleet f("&options=-c%20lock_timeout%3D150");  // ms: the server's statements wait that long for a lock
  ASSERT_GT(f.server->port(), 0) << f.server->output() << "\n" << f.log();
  httplib::Client client("127.0.0.1", f.server->port());
  const nlohmann::json question = {{"class", "near-edge"}, {"top_k", 3}, {"region", {{"bbox", {-5, -5, -1, 20, 20, 2}}}}};
  ASSERT_EQ(post(client, "/api/query", question).first, 200) << f.log();
  pqxx::connection other(f.url);
  {
    pqxx::work holding(other);
    holding.exec("LOCK TABLE slamvdb.submaps IN ACCESS EXCLUSIVE MODE");
    const auto [status, error] = post(client, "/api/query", question);
    EXPECT_EQ(status, 503) << error.dump();
    EXPECT_NE(error.dump().find("lock timeout"), std::string::npos) << error.dump();
    EXPECT_EQ(get(client, "/api/classes?bbox=-5,-5,-1,20,20,2").first, 503);
    EXPECT_EQ(get(client, "/healthz").first, 200);  // its count: the last one the database gave
  }  // rolled back: the lock is gone
  ASSERT_EQ(post(client, "/api/query", question).first, 200) << f.log();
  {
    pqxx::work damage(other);
    damage.exec("UPDATE slamvdb.occupancy SET crc = crc # 1 WHERE submap = 0");
    damage.commit();
  }
  const auto [status, error] = post(client, "/api/query", question);
  EXPECT_EQ(status, 500) << error.dump();
  EXPECT_NE(error.dump().find("CRC mismatch"), std::string::npos) << error.dump();
  EXPECT_EQ(post(client, "/api/at", {{"points", {{1, 1, 0.1}}}}).first, 500);
  EXPECT_TRUE(f.server->running()) << f.log();
}

// /metrics, /healthz and the answers' semantic_cells count the catalog as it is now (within a
// second), not as it was when the server started: a session pushed while serving shows.
TEST(ServeFleet, TheSemanticCellCountFollowsAPushWhileServing) {
  ServedFleet f;
  ASSERT_GT(f.server->port(), 0) << f.server->output() << "\n" << f.log();
  httplib::Client client("127.0.0.1", f.server->port());
  const auto metrics_count = [&] {
    const auto res = client.Get("/metrics");
    std::smatch m;
    const std::string text = res ? res->body : "";
    return std::regex_search(text, m, std::regex(R"(\nslamvdb_map_semantic_cells (\d+))")) ? std::stoull(m[1].str()) : 0ull;
  };
  const auto catalog_count = [&] {
    std::size_t n = 0;
    for (const CatalogSubmap& m : FleetDatabase(f.url).catalog().submaps) n += m.semantic_voxels;
    return n;
  };
  const std::size_t before = catalog_count();
  ASSERT_GT(before, 0u);
  EXPECT_EQ(metrics_count(), before);
  FleetDatabase(f.url).push_map(slamvdb::testing::patch_map(2, 40), {.session = "wednesday"});
  const std::size_t after = catalog_count();
  ASSERT_GT(after, before);
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // FleetMapService::kCountMaxAge
  EXPECT_EQ(metrics_count(), after);
  EXPECT_EQ(get(client, "/healthz").second.at("semantic_cells").get<std::size_t>(), after);
  const auto [status, answer] = post(client, "/api/query", {{"class", "near-edge"}, {"top_k", 1}, {"region", {{"bbox", {-5, -5, -1, 20, 20, 2}}}}});
  ASSERT_EQ(status, 200) << answer.dump();
  EXPECT_EQ(answer.at("semantic_cells").get<std::size_t>(), after);
  EXPECT_EQ(get(client, "/api/info").second.at("voxels").at("semantic").get<std::size_t>(), after);
}

// GET /api/nav-grid on a fleet: the region's submaps pulled, then the map file's code; the bytes
// of `classify --db --bbox ... --grid PREFIX` on the same region (PGM, PNG; the YAML but for its
// image name).
TEST(ServeFleet, TheNavGridOfARegionIsTheBytesOfClassifyDbGrid) {
  // The test's classes have no default navigation cost (query/nav_grid.hpp): given, the same to both.
  ServedFleet f("", {"--cost", "near-edge=0", "--cost", "far-edge=30"});
  ASSERT_GT(f.server->port(), 0) << f.server->output() << "\n" << f.log();
  httplib::Client client("127.0.0.1", f.server->port());
  const std::string bbox = "95,-5,-1,140,20,2";  // both sessions' second patch, overlapping
  const auto prefix = f.tmp.path / "grid";
  const auto r = run_command(shell_quote(SLAMVDB_CLI_PATH) + " classify --db " + shell_quote(f.url) + " --queries " +
                             shell_quote(f.queries.string()) + " --cost near-edge=0 --cost far-edge=30 --bbox=" + bbox + " --grid " +
                             shell_quote(prefix.string()) + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto served = [&](const std::string& format) {
    const auto res = client.Get("/api/nav-grid?bbox=" + bbox + "&format=" + format);
    EXPECT_TRUE(res && res->status == 200) << (res ? res->body : "no answer") << "\n" << f.log();
    return res ? res->body : std::string();
  };
  const std::string pgm = slamvdb::testing::read_text_file(prefix.string() + ".pgm");
  EXPECT_EQ(served("pgm"), pgm);
  EXPECT_EQ(served("png"), slamvdb::testing::read_text_file(prefix.string() + ".png"));
  std::string yaml = served("yaml");
  const auto image = yaml.find("nav-grid.pgm");
  ASSERT_NE(image, std::string::npos) << yaml;
  EXPECT_EQ(yaml.replace(image, std::string("nav-grid.pgm").size(), "grid.pgm"),
            slamvdb::testing::read_text_file(prefix.string() + ".yaml"));
  // Not an empty picture: the region's patches are known cells (pixels not 255, unknown).
  std::istringstream header(pgm);
  std::string magic;
  int width = 0, height = 0, maxval = 0;
  header >> magic >> width >> height >> maxval;
  ASSERT_EQ(magic, "P5");
  const std::size_t cells = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  ASSERT_GT(cells, 0u);
  ASSERT_GE(pgm.size(), cells);
  EXPECT_GT(std::count_if(pgm.end() - static_cast<std::ptrdiff_t>(cells), pgm.end(),
                          [](char c) { return static_cast<uint8_t>(c) != 255; }),
            0);
}

TEST(ServeFleet, TheDatabaseIsCheckedBeforeListeningAndAMapFileWithDbIsAUsageError) {
  slamvdb::testing::TempDir tmp;
  auto& postgres = slamvdb::testing::shared_postgres_server();
  const std::string serve = shell_quote(SLAMVDB_CLI_PATH) + " serve --port 0 --db ";
  const auto empty = run_command(serve + shell_quote(postgres.url(slamvdb::testing::fresh_test_database(postgres))) + " 2>&1");
  EXPECT_EQ(empty.exit_code, 1) << empty.output;
  EXPECT_NE(empty.output.find("holds no fleet map"), std::string::npos) << empty.output;
  const std::string nowhere = "postgresql://robot:s3cret@/fleet?host=" + (tmp.path / "none").string();
  const auto down = run_command(serve + shell_quote(nowhere) + " 2>&1");
  EXPECT_EQ(down.exit_code, 1) << down.output;
  EXPECT_NE(down.output.find("cannot connect to the fleet database postgresql://robot:***@"), std::string::npos)
      << down.output;
  EXPECT_EQ(down.output.find("s3cret"), std::string::npos) << down.output;
  const auto file = tmp.path / "m.svdb";
  save_map(file, slamvdb::testing::patch_map(1, 4));
  const auto both = run_command(serve + "x " + shell_quote(file.string()) + " 2>&1");
  EXPECT_EQ(both.exit_code, 2) << both.output;
  EXPECT_EQ(run_command(shell_quote(SLAMVDB_CLI_PATH) + " serve --port 0 2>&1").exit_code, 2);
}

}  // namespace
}  // namespace slamvdb::fleet
