// The web console's page (station/web_page/), embedded at build time by cmake/EmbedFiles.cmake,
// so revolved serves it with no files to install.
#pragma once

#include <span>
#include <string_view>

namespace revolve::station {

struct WebAsset {
  std::string_view path;          // URL path: "/" (index.html), "/app.js", ...
  std::string_view content_type;  // "text/html; charset=utf-8", ...
  std::string_view bytes;
};

std::span<const WebAsset> WebAssets();

}  // namespace revolve::station
