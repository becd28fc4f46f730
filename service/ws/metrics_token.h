#pragma once
// The bearer token that opens GET /metrics at the WebSocket door
// (websocket.metrics_token_file, docs/DEPLOY.md "Metrics"). The file is
// checked as the key files are: a regular file of mode 600 (or stricter),
// one line of 32-256 visible ASCII characters (no spaces), e.g.
// `openssl rand -hex 32`.

#include <string>

namespace sweptccd::ws {

/// The token; throws InputError with one line naming the file and the fix.
std::string LoadMetricsToken(const std::string& path);

}  // namespace sweptccd::ws
