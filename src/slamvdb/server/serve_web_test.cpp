// The page `slamvdb serve` answers at /: only the embedded page and script are served (no path of a
// request reaches a file), and in Debian's headless chromium the page draws the map, hides a class
// layer, and highlights the answer to a typed question where `slamvdb query` puts it. GET
// /api/events streams the map's change counter, to a bounded number of clients.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>
#include <nlohmann/json.hpp>

#include "slamvdb/server/web_assets.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::run_command;
using testing::shell_quote;

TEST(ServeWeb, ServesOnlyTheEmbeddedPageAndScript) {
  if (!web_page_available()) GTEST_SKIP() << "built without the page (npm ci --prefix viewer)";
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto page = s.client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_EQ(page->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(page->body.find("<script src=\"/assets/serve.js\">"), std::string::npos);
  const auto script = s.client.Get("/assets/serve.js");
  ASSERT_TRUE(script);
  EXPECT_EQ(script->status, 200);
  EXPECT_EQ(script->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_GT(script->body.size(), 100000u);  // three.js is in it
  EXPECT_NE(script->body.find("/api/points"), std::string::npos);
  // Anything else is no route (JSON 404), whatever it names; another method on the page is 405.
  for (const std::string path : {"/index.html", "/assets/viewer.js", "/assets/../CMakeLists.txt",
                                 "/assets/%2e%2e/%2e%2e/CMakeLists.txt", "/assets/serve.js/x", "//etc/passwd"}) {
    const auto res = s.client.Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 404) << path << "\n" << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json") << path;
  }
  const auto post = s.client.Post("/", "{}", "application/json");
  ASSERT_TRUE(post);
  EXPECT_EQ(post->status, 405);
}

// World positions of `slamvdb query --text TEXT`'s best cells: every cell within 1e-4 of the top score.
std::vector<Vec3d> cli_best_cells(const testing::ServedMap& s, const std::string& text) {
  const auto run = [&](const std::string& args) {
    const auto out = s.f.tmp.path / "answer.csv";
    const auto r = run_command(s.f.cli("query " + shell_quote(s.f.map.string()) + " --text " + shell_quote(text) + " " +
                                       args + " --ignore-model-id -o " + shell_quote(out.string())));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::string error;
    auto records = testing::read_csv_strict(testing::read_text_file(out), &error);
    EXPECT_TRUE(records && records->size() > 1) << error;
    return records ? std::vector<std::vector<std::string>>(records->begin() + 1, records->end())
                   : std::vector<std::vector<std::string>>{};
  };
  const auto top = run("--top-k 1");  // rank,x,y,z,score,...
  if (top.empty()) return {};
  const double best = std::stod(top[0][4]);
  std::vector<Vec3d> cells;
  for (const auto& row : run(fmt::format("--top-k 0 --threshold {}", best - 1e-4)))
    cells.emplace_back(std::stod(row[1]), std::stod(row[2]), std::stod(row[3]));
  return cells;
}

TEST(ServeWeb, PageHighlightsTheClisAnswerInChromium) {
  if (!web_page_available()) GTEST_SKIP() << "built without the page (npm ci --prefix viewer)";
  if (!fs::exists("/usr/bin/chromium")) GTEST_SKIP() << "Debian's chromium is missing (scripts/setup.sh installs it)";
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const std::vector<Vec3d> best = cli_best_cells(s, "grass");
  ASSERT_GT(best.size(), 10u);
  nlohmann::json points = nlohmann::json::array();
  for (const Vec3d& p : best) points.push_back({p.x(), p.y(), p.z()});
  const fs::path script = fs::path(SLAMVDB_SOURCE_DIR) / "viewer/test/serve_page.mjs";
  const fs::path shot = s.f.tmp.path / "page.png";
  const auto r = run_command(
      fmt::format("cd {} && exec node {} {} grass {} {}", shell_quote(SLAMVDB_SOURCE_DIR), shell_quote(script.string()),
                  shell_quote(fmt::format("http://127.0.0.1:{}/", s.server.port())), shell_quote(shot.string()),
                  shell_quote(points.dump())),
      180.0);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto result = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  ASSERT_TRUE(result["ready"].get<bool>()) << r.output << "\n" << s.log();
  std::cout << "page in chromium: " << result.dump() << "\n";  // the figures, for the log
  EXPECT_TRUE(result["errors"].empty()) << r.output;
  EXPECT_TRUE(result["requests"].empty()) << r.output;  // nothing but the server was asked
  EXPECT_GT(result["points"].get<int>(), 100);
  const double pixels = result["pixels"].get<double>();
  EXPECT_GT(result["drawn"].get<double>(), 0.05 * pixels) << r.output;
  // Hiding the first class's layer hides its points.
  EXPECT_LT(result["drawn_without_first_class"].get<double>(), 0.9 * result["drawn"].get<double>()) << r.output;
  // The heat map: hot pixels, centred where the CLI's best cells are drawn.
  EXPECT_GT(result["hot"].get<double>(), 0.01 * pixels) << r.output;
  ASSERT_TRUE(result["hot_centroid"].is_array()) << r.output;
  const double dx = result["hot_centroid"][0].get<double>() - result["answer_centroid"][0].get<double>();
  const double dy = result["hot_centroid"][1].get<double>() - result["answer_centroid"][1].get<double>();
  EXPECT_LT(std::hypot(dx, dy), 80.0) << r.output;  // of an 800 x 600 view
  EXPECT_NE(result["colour_bar"].get<std::string>().find("grass"), std::string::npos) << r.output;
  // A click on one of the best cells shows what /api/at says of it: a class and its count.
  const std::string picked = result["picked"].get<std::string>();
  EXPECT_TRUE(picked.find("class: smooth") != std::string::npos || picked.find("class: rough") != std::string::npos)
      << picked;
  EXPECT_NE(picked.find("observations: "), std::string::npos) << picked;
  EXPECT_NE(picked.find("score: "), std::string::npos) << picked;
  EXPECT_GT(fs::file_size(shot), 1000u);
}

// Reads GET /api/events until the first event is complete; returns what was received.
std::string first_event(int port) {
  httplib::Client client("127.0.0.1", port);
  std::string received;
  client.Get("/api/events", [&](const char* data, std::size_t n) {
    received.append(data, n);
    return received.find("\n\n") == std::string::npos;  // stop after one event
  });
  return received;
}

TEST(ServeWeb, EventsStreamTheChangeCounterToBoundedClients) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const std::string event = first_event(s.server.port());
  EXPECT_EQ(event.rfind("retry: 2000\nid: 0\nevent: map\ndata: ", 0), 0u) << event;
  const auto data = nlohmann::json::parse(event.substr(event.find("data: ") + 6));
  EXPECT_EQ(data.at("changes"), 0);  // a saved map never changes
  EXPECT_EQ(data.at("semantic_cells").get<std::size_t>(), s.f.semantic_cells);
  EXPECT_EQ(data.at("submaps"), 1);
  // Four streams open (each holds a worker): a fifth is refused with 503 at once, not queued.
  constexpr int kStreams = 4;
  std::vector<std::unique_ptr<httplib::Client>> clients;
  std::vector<std::thread> readers;
  std::atomic<int> started{0};
  for (int i = 0; i < kStreams; ++i) {
    clients.push_back(std::make_unique<httplib::Client>("127.0.0.1", s.server.port()));
    readers.emplace_back([&, c = clients.back().get()] {
      c->Get("/api/events", [&](const char*, std::size_t) {
        ++started;
        return true;
      });
    });
  }
  for (int wait = 0; wait < 200 && started < kStreams; ++wait) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GE(started.load(), kStreams);
  const auto refused = s.client.Get("/api/events");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 503) << refused->body;
  EXPECT_EQ(refused->get_header_value("Content-Type"), "application/json");
  EXPECT_FALSE(refused->get_header_value("Retry-After").empty());
  for (auto& c : clients) c->stop();
  for (auto& t : readers) t.join();
  // The streams are released when their clients leave (noticed at a heartbeat): a new one is served.
  std::string again;
  for (int wait = 0; wait < 150 && again.find("event: map") == std::string::npos; ++wait) {
    again = first_event(s.server.port());
    if (again.find("event: map") == std::string::npos) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_NE(again.find("event: map"), std::string::npos) << again;
  const auto other = s.client.Get("/api/events?since=3");
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 400);  // no parameters
}

}  // namespace
}  // namespace slamvdb
