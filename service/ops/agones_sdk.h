#pragma once
// The Agones SDK sidecar's REST API (agones.dev "REST Game Server Client
// API"; sdks/ and site/content in github.com/googleforgames/agones) over
// libcurl, as Agones' C++ SDK needs a newer protobuf than Debian ships:
// POST /ready, /health, /shutdown with the empty JSON object, GET
// /gameserver, and the stream GET /watch/gameserver (one JSON object a line,
// {"result": GameServer}, each time the GameServer changes). The sidecar listens on
// localhost:$AGONES_SDK_HTTP_PORT. Every call has a short timeout and returns false on failure
// (logged).

#include <functional>
#include <string>

namespace sweptccd {

class AgonesSdk {
 public:
  /// http://localhost:PORT with PORT from AGONES_SDK_HTTP_PORT. Throws
  /// InputError when it is unset or not a port number.
  static std::string BaseUrlFromEnvironment();

  explicit AgonesSdk(std::string base_url);
  bool Ready() { return Post("/ready"); }
  bool Health() { return Post("/health"); }
  bool Shutdown() { return Post("/shutdown"); }
  /// GET /gameserver: the GameServer as JSON (at most 1 MiB), empty on failure.
  std::string GetGameServer();
  /// The longest line GET /watch/gameserver may send, bytes: a longer one
  /// ends the stream (a GameServer is a few KiB).
  static constexpr size_t kMaxWatchObjectBytes = 256 * 1024;
  /// GET /watch/gameserver: `on_connected` once the sidecar answered 200,
  /// then `on_object` with each line (without its newline; empty lines
  /// skipped), until the stream ends or fails (false, `error` says why in
  /// one escaped line: not logged, the caller retries) or `stop`
  /// returns true (polled every 100 ms; true). Connecting times out as the
  /// other calls; the stream itself has no time limit.
  bool WatchGameServer(const std::function<void(const std::string&)>& on_object,
                       const std::function<void()>& on_connected, const std::function<bool()>& stop,
                       std::string* error);

 private:
  bool Post(const char* path);
  std::string base_url_;
};

}  // namespace sweptccd
