#pragma once
// The WebSocket door's settings (docs/WEBSOCKET.md; flags --ws-*, YAML
// `websocket:`). Off unless `listen` is set.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sweptccd {

inline constexpr int64_t kDefaultIdleTimeoutMs = 15000;

struct WsDoorOptions {
  std::string listen;                      // HOST:PORT; empty: no door.
  std::string cert_path;                   // PEM certificate chain: TLS (wss://) with key_path.
  std::string key_path;                    // PEM private key.
  std::vector<std::string> allow_origins;  // Browser origins allowed besides the door's own.
  std::string view_dir;                    // The live view's files; empty: the build's view folder.
  /// A file holding the bearer token for GET /metrics at the door (the
  /// Prometheus text, as --metrics-listen serves it on loopback); empty:
  /// the door does not serve /metrics (404). Needs TLS (cert, key) unless
  /// the door listens on loopback: a token never crosses a network in clear.
  std::string metrics_token_path;
  int max_connections = 64;
  int max_connections_per_address = 8;
  int64_t handshake_timeout_ms = 5000;  // TCP accept -> upgrade done.
  /// No frame for this long: closed; 0: the larger of silence_timeout_ms
  /// and kDefaultIdleTimeoutMs.
  int64_t idle_timeout_ms = 0;
  size_t max_message_bytes = 256 * 1024;
  double message_rate_hz = 480;  // Per connection, every message.
  int message_burst = 64;
  size_t send_queue_messages = 256;
  size_t send_queue_bytes = 4 << 20;
  int max_objects_per_connection = 16;
  int max_scene_triangles = 200000;  // The display meshes together, at most.
  /// The kernel's send buffer of each accepted socket (SO_SNDBUF), bytes:
  /// bounds what a reader that stalls holds besides the send queue.
  int socket_send_buffer_bytes = 256 * 1024;
};

/// "" when `options` is consistent (ports, positive caps, cert and key
/// together), else one line naming the setting and the fix.
std::string ValidateWsDoorOptions(const WsDoorOptions& options);

/// Whether HOST of HOST:PORT is a loopback address (127.0.0.0/8, ::1,
/// "localhost").
bool IsLoopbackListen(const std::string& listen);

}  // namespace sweptccd
