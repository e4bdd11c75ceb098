// The web console and HTTP API of revolved ([web], docs/web-console.md, docs/api/openapi.json).
//
// cpp-httplib (Debian's libcpp-httplib-dev) serves it: a maintained library, already in Debian,
// with server-sent events through its chunked content provider, request size and timeout limits
// built in, and no event loop of its own to fit into the daemon's. Each connection is served on
// its own thread (at most [web] max_connections at once; more wait for a free one), so a slow or
// stalled client holds only its own thread, never the scanning thread or the daemon's loop.
//
// What the server shows comes from the daemon through StationControl (run on the daemon's main
// loop: the same code the control socket calls), the EventHub (the same events the socket's
// watchers get, with the same fields) and the LiveView (latest frame, coarse hull).
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "station/event_hub.h"
#include "station/live_view.h"
#include "station/station_config.h"

namespace revolve::station {

// The daemon's side of the API; each call may come from any server thread.
struct StationControl {
  std::function<Expected<nlohmann::json>()> status;  // the socket's "status" object
  // {"id", "dir", "recipe", "resumed"}. Errors: busy (a scan runs), bad_input, not_found, ...
  std::function<Expected<nlohmann::json>(const std::optional<std::string>& recipe,
                                         const std::optional<std::string>& resume)>
      start;
  std::function<Expected<nlohmann::json>()> abort;  // {"scan_id"}; bad_input: nothing runs
  std::function<Expected<nlohmann::json>()> list;   // the socket's "scans" array
};

// The HTTP status for an error code: busy 409, bad_input 400, not_found 404, no_device 503, ...
int HttpStatusFor(ErrorCode code);

// The file `relative` (as decoded from the URL) inside scan `scan_id` of `scans_dir`: a regular
// file whose real path (symlinks resolved) lies inside the scan's folder. Errors: bad_input for
// an invalid scan id, an absolute path, an empty, "." or ".." component or a NUL or backslash;
// not_found for a missing file or one whose real path leaves the folder.
Expected<std::filesystem::path> ResolveScanFile(const std::filesystem::path& scans_dir,
                                                std::string_view scan_id,
                                                std::string_view relative);

// The Content-Type of a scan file or asset, by extension ("application/octet-stream" otherwise).
std::string_view ContentTypeFor(const std::filesystem::path& path);

// The first line of web.token_file, without surrounding blanks. Errors: not_found / io / bad_input
// (empty), naming web.token_file and the file.
Expected<std::string> ReadWebToken(const std::filesystem::path& token_file);

// Where Debian's libjs-three keeps three.js: $REVOLVE_THREE_DIR, the folder found at build time,
// /usr/share/javascript/three; the first holding three.min.js. nullopt: none (the page then
// shows no 3D view and says why).
std::optional<std::filesystem::path> FindThreeJs();

class WebServer {
 public:
  // Binds `options.listen` and serves on its own threads until Stop(). `token` empty: no token
  // (loopback only; the configuration refuses other hosts without one). `hub` and `live` are
  // borrowed and must outlive the server. Errors: bad_input for a malformed listen, io naming
  // web.listen when the address cannot be bound (in use, not local).
  static Expected<std::unique_ptr<WebServer>> Start(const WebOptions& options, std::string token,
                                                    std::filesystem::path scans_dir,
                                                    StationControl control, const EventHub& hub,
                                                    LiveView* live);
  ~WebServer();  // Stop()
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Ends the event streams, closes the listener and waits for the connections' threads (a
  // stalled client's for at most [web] timeout_s). Idempotent.
  void Stop();

  int port() const;
  // "http://127.0.0.1:8080/"
  std::string url() const;

  class Impl;

 private:
  explicit WebServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace revolve::station
