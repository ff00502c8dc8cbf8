#include "slamvdb/io/html_viewer.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"

namespace slamvdb {
namespace {

#ifdef SLAMVDB_HAVE_HTML_VIEWER
#include "slamvdb/io/viewer_script.inc"
#else
const std::string_view kViewerScript{};
#endif

// Base64 (RFC 4648) by hand: a dozen lines, and no library we link has a public encoder.
std::string base64(const std::vector<std::uint8_t>& bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const std::uint32_t v = bytes[i] << 16 | bytes[i + 1] << 8 | bytes[i + 2];
    for (int shift : {18, 12, 6, 0}) out += kAlphabet[(v >> shift) & 63];
  }
  if (const std::size_t rest = bytes.size() - i; rest > 0) {
    const std::uint32_t v = bytes[i] << 16 | (rest == 2 ? bytes[i + 1] << 8 : 0);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += rest == 2 ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

// JSON inside <script>: "</" would end the element early.
std::string script_safe(std::string text) {
  for (std::size_t at = 0; (at = text.find("</", at)) != std::string::npos; at += 3) text.replace(at, 2, "<\\/");
  return text;
}

std::string html_escape(std::string_view text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

constexpr std::string_view kStyle = R"(
html, body { margin: 0; height: 100%; overflow: hidden; background: #101418; font: 13px sans-serif; }
#slamvdb-panel { position: absolute; top: 8px; left: 8px; padding: 8px 10px; color: #e8e8e8;
  background: rgba(0, 0, 0, 0.55); border-radius: 4px; max-width: 360px; }
#slamvdb-panel .title { font-weight: bold; margin-bottom: 4px; }
#slamvdb-panel .legend { margin-top: 2px; }
#slamvdb-panel .swatch { display: inline-block; width: 12px; height: 12px; margin-right: 6px; vertical-align: -2px; }
#slamvdb-panel .colour-bar { height: 12px; margin-top: 6px; }
#slamvdb-panel .colour-bar-labels { display: flex; justify-content: space-between; }
)";

}  // namespace

bool html_viewer_available() { return !kViewerScript.empty(); }

void write_html_viewer(const std::filesystem::path& path, const HtmlViewerScene& scene) {
  if (!html_viewer_available())
    throw Error("this slamvdb was built without the HTML viewer: run `npm ci --prefix viewer` in the source tree "
                "(scripts/setup.sh does) and rebuild");
  const std::size_t n = scene.positions.size();
  if (scene.colours.size() != n)
    throw Error(fmt::format("HTML viewer: {} positions but {} colours", n, scene.colours.size()));
  if (!(scene.voxel_size > 0 && std::isfinite(scene.voxel_size)))
    throw Error(fmt::format("HTML viewer: voxel size {} is not a positive number", scene.voxel_size));

  // Positions relative to the centroid: float32 keeps millimetres near the map, not 1e5 m away.
  Vec3d origin = Vec3d::Zero();
  for (const Vec3d& p : scene.positions) {
    if (!p.allFinite()) throw Error("HTML viewer: a position is not finite");
    origin += p / static_cast<double>(n);
  }
  std::vector<std::uint8_t> bytes(n * 15);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f local = (scene.positions[i] - origin).cast<float>();
    std::memcpy(bytes.data() + i * 12, local.data(), 12);  // little endian, as JavaScript's typed arrays here
    std::memcpy(bytes.data() + n * 12 + i * 3, scene.colours[i].data(), 3);
  }

  nlohmann::json meta = {{"title", scene.title},
                         {"count", n},
                         {"voxel_size", scene.voxel_size},
                         {"origin", {origin.x(), origin.y(), origin.z()}},
                         {"legend", nlohmann::json::array()}};
  for (const auto& entry : scene.legend) meta["legend"].push_back({{"name", entry.name}, {"color", entry.colour}});
  if (scene.colour_bar) {
    const auto& bar = *scene.colour_bar;
    meta["colour_bar"] = {{"label", bar.label}, {"min", bar.min}, {"max", bar.max}, {"stops", bar.stops}};
  }

  std::string page;
  page.reserve(kViewerScript.size() + bytes.size() * 4 / 3 + 4096);
  page += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>";
  page += html_escape(scene.title);
  page += "</title>\n<style>";
  page += kStyle;
  page += "</style>\n</head>\n<body>\n<div id=\"slamvdb-panel\"></div>\n";
  page += "<script id=\"slamvdb-meta\" type=\"application/json\">";
  page += script_safe(meta.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  page += "</script>\n<script id=\"slamvdb-points\" type=\"application/octet-stream\">";
  page += base64(bytes);
  page += "</script>\n<script>\n";
  page += kViewerScript;
  page += "\n</script>\n</body>\n</html>\n";
  write_output_file(path, page);
}

}  // namespace slamvdb
