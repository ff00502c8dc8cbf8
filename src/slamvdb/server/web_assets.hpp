#pragma once
// The page `slamvdb serve` answers at / and its script: compiled into the library at build time
// (viewer/src/serve_page.js bundled with three.js by esbuild, as the HTML export's viewer), so the
// server never reads a file named by a request and the page needs no network but the server.
#include <string_view>

namespace slamvdb {

struct WebAsset {
  std::string_view body;
  std::string_view content_type;
};

// Whether this build has the page (needs the viewer's npm packages at build time).
bool web_page_available();

// The asset at a request path: "/" (the page) or "/assets/serve.js" (its script). Throws
// RequestError 404 for any other path, and 404 saying how to build it when the page is not built in.
WebAsset web_asset(std::string_view path);

}  // namespace slamvdb
