// The HTML viewer page: self-contained (no external URL), data that round-trips, and a real
// rendering in headless chromium (the npm packages and Debian's chromium, installed by setup.sh).
#include "slamvdb/io/html_viewer.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

// A 40 x 40 ground patch (green) with a 3 m red pole, 1e5 m from the origin.
HtmlViewerScene test_scene() {
  HtmlViewerScene scene;
  scene.title = "test <map> & \"scene\"</script>";
  scene.voxel_size = 0.25;
  const Vec3d far(1e5, -2e5, 30);
  for (int x = 0; x < 40; ++x)
    for (int y = 0; y < 40; ++y) {
      scene.positions.push_back(far + Vec3d(x * 0.25, y * 0.25, 0));
      scene.colours.push_back({40, 200, 60});
    }
  for (int z = 1; z <= 12; ++z) {
    scene.positions.push_back(far + Vec3d(5, 5, z * 0.25));
    scene.colours.push_back({230, 30, 30});
  }
  scene.legend = {{"smooth", {40, 200, 60}}, {"obstacle", {230, 30, 30}}};
  return scene;
}

using testing::read_text_file;

TEST(HtmlViewer, PageIsSelfContainedAndEscaped) {
  if (!html_viewer_available()) GTEST_SKIP() << "built without the viewer (npm ci --prefix viewer)";
  testing::TempDir tmp;
  const fs::path page = tmp.path / "map.html";
  write_html_viewer(page, test_scene());
  const std::string html = read_text_file(page);
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  // No resource is fetched: no src=/href= attributes, no http(s) URL outside comments of the bundle.
  EXPECT_FALSE(std::regex_search(html, std::regex(R"((src|href)\s*=\s*["']?https?:)")));
  EXPECT_EQ(html.find("<script src"), std::string::npos);
  EXPECT_NE(html.find("<title>test &lt;map&gt; &amp; &quot;scene&quot;&lt;/script&gt;</title>"), std::string::npos);
  // The meta block parses and its point count matches; the title cannot end the script early.
  const std::smatch m = [&] {
    std::smatch found;
    std::regex_search(html, found, std::regex(R"(<script id="slamvdb-meta" type="application/json">(.*?)</script>)"));
    return found;
  }();
  ASSERT_EQ(m.size(), 2u);
  const auto meta = nlohmann::json::parse(m[1].str());
  EXPECT_EQ(meta["count"], 1612);
  EXPECT_EQ(meta["title"], "test <map> & \"scene\"</script>");
  EXPECT_NEAR(meta["origin"][0].get<double>(), 1e5 + 4.9, 0.2);
}

TEST(HtmlViewer, RefusesInconsistentScenes) {
  testing::TempDir tmp;
  HtmlViewerScene scene = test_scene();
  scene.colours.pop_back();
  EXPECT_THROW(write_html_viewer(tmp.path / "a.html", scene), Error);
  scene = test_scene();
  scene.positions[3].x() = std::nan("");
  EXPECT_THROW(write_html_viewer(tmp.path / "b.html", scene), Error);
  EXPECT_FALSE(fs::exists(tmp.path / "a.html"));
  EXPECT_FALSE(fs::exists(tmp.path / "b.html"));
}

TEST(HtmlViewer, RendersInHeadlessChromium) {
  if (!html_viewer_available()) GTEST_SKIP() << "built without the viewer (npm ci --prefix viewer)";
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "Debian's chromium is missing (scripts/setup.sh installs it)";
  testing::TempDir tmp;
  const fs::path page = tmp.path / "map.html", shot = tmp.path / "map.png";
  write_html_viewer(page, test_scene());
  const fs::path script = fs::path(SLAMVDB_SOURCE_DIR) / "viewer/test/screenshot.mjs";
  const auto r = testing::run_command(fmt::format("cd {} && exec node {} {} {}", testing::shell_quote(SLAMVDB_SOURCE_DIR),
                                                  testing::shell_quote(script.string()),
                                                  testing::shell_quote(page.string()),
                                                  testing::shell_quote(shot.string())),
                                      120.0);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto result = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  ASSERT_TRUE(result["ready"].get<bool>()) << r.output;
  EXPECT_EQ(result["points"], 1612);
  EXPECT_TRUE(result["errors"].empty()) << r.output;
  EXPECT_TRUE(result["requests"].empty()) << r.output;  // nothing fetched from a network
  // The points cover a visible part of the view (a 10 m patch seen from its own size away).
  const double drawn = result["drawn"].get<double>() / result["pixels"].get<double>();
  EXPECT_GT(drawn, 0.02) << r.output;
  EXPECT_EQ(result["legend"], nlohmann::json({"smooth", "obstacle"}));
  EXPECT_GT(fs::file_size(shot), 1000u);
}

}  // namespace
}  // namespace slamvdb
