#include "slamvdb/server/web_assets.hpp"

#include <fmt/format.h>

#include <string_view>

#include "slamvdb/server/request_decoding.hpp"

namespace slamvdb {

namespace web_assets_script {
#if defined(SLAMVDB_HAVE_SERVE_PAGE)
#include "slamvdb/server/serve_page_script.inc"
#else
const std::string_view kViewerScript;
#endif
}  // namespace web_assets_script

namespace web_assets_detail {

constexpr std::string_view kPage = R"(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>slamvdb serve</title>
<style>
html, body { margin: 0; height: 100%; overflow: hidden; background: #101418; font: 13px sans-serif; }
#slamvdb-panel { position: absolute; top: 8px; left: 8px; padding: 8px 10px; color: #e8e8e8;
  background: rgba(0, 0, 0, 0.55); border-radius: 4px; max-width: 360px; }
#slamvdb-panel .title { font-weight: bold; margin-bottom: 4px; }
#slamvdb-panel input#slamvdb-query { width: 100%; box-sizing: border-box; margin: 6px 0 2px; }
#slamvdb-panel .legend { display: block; margin-top: 2px; }
#slamvdb-panel .swatch { display: inline-block; width: 12px; height: 12px; margin: 0 6px 0 2px; vertical-align: -2px; }
#slamvdb-panel .colour-bar { height: 12px; margin-top: 6px; }
#slamvdb-panel .colour-bar-labels { display: flex; justify-content: space-between; }
#slamvdb-panel .picked { white-space: pre; margin-top: 6px; }
</style>
</head>
<body>
<div id="slamvdb-panel"></div>
<script src="/assets/serve.js"></script>
</body>
</html>
)";

}  // namespace web_assets_detail

bool web_page_available() { return !web_assets_script::kViewerScript.empty(); }

WebAsset web_asset(std::string_view path) {
  if (path != "/" && path != "/assets/serve.js") throw RequestError(404, "", fmt::format("no route {}", path));
  if (!web_page_available())
    throw RequestError(404, "", "this server was built without its page (run `npm ci --prefix viewer` and rebuild)");
  if (path == "/") return {web_assets_detail::kPage, "text/html; charset=utf-8"};
  return {web_assets_script::kViewerScript, "text/javascript; charset=utf-8"};
}

}  // namespace slamvdb
