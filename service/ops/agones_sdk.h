#pragma once
// The Agones SDK sidecar's REST API (agones.dev "REST Game Server Client
// API"; sdks/ and site/content in github.com/googleforgames/agones) over
// libcurl, as Agones' C++ SDK needs a newer protobuf than Debian ships:
// POST /ready, /health, /shutdown with the empty JSON object, GET
// /gameserver. The sidecar listens on localhost:$AGONES_SDK_HTTP_PORT.
// Every call has a short timeout and returns false on failure (logged).

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

 private:
  bool Post(const char* path);
  std::string base_url_;
};

}  // namespace sweptccd
