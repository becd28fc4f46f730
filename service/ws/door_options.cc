#include "service/ws/door_options.h"

#include <arpa/inet.h>

namespace sweptccd {

namespace {

// HOST and PORT of HOST:PORT or [HOST]:PORT; false when malformed.
bool SplitListen(const std::string& listen, std::string* host, int* port) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 >= listen.size()) return false;
  *host = listen.substr(0, colon);
  if (host->size() >= 2 && host->front() == '[' && host->back() == ']') {
    *host = host->substr(1, host->size() - 2);
  }
  const std::string p = listen.substr(colon + 1);
  if (p.size() > 5 || p.find_first_not_of("0123456789") != std::string::npos) return false;
  *port = std::stoi(p);
  return !host->empty() && *port <= 65535;
}

}  // namespace

bool IsLoopbackListen(const std::string& listen) {
  std::string host;
  int port = 0;
  if (!SplitListen(listen, &host, &port)) return false;
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

std::string ValidateWsDoorOptions(const WsDoorOptions& o) {
  if (o.listen.empty()) return "";
  std::string host;
  int port = 0;
  if (!SplitListen(o.listen, &host, &port)) {
    return "websocket.listen '" + o.listen + "': give HOST:PORT, e.g. 127.0.0.1:8765";
  }
  if (o.cert_path.empty() != o.key_path.empty()) {
    return "websocket: give both --ws-cert and --ws-key (PEM files) for TLS, or neither";
  }
  if (!o.metrics_token_path.empty() && o.cert_path.empty() && !IsLoopbackListen(o.listen)) {
    return "websocket.metrics_token_file: /metrics with a bearer token off loopback needs TLS; "
           "give --ws-cert and --ws-key, or listen on 127.0.0.1";
  }
  if (o.max_connections < 1 || o.max_connections_per_address < 1) {
    return "websocket: max_connections and max_connections_per_address must be >= 1";
  }
  if (o.handshake_timeout_ms < 1 || o.idle_timeout_ms < 0) {
    return "websocket: handshake_timeout_ms must be >= 1 and idle_timeout_ms >= 0";
  }
  if (o.max_message_bytes < 1024 || o.max_message_bytes > (64u << 20)) {
    return "websocket.max_message_bytes must lie in [1024, 67108864]";
  }
  if (!(o.message_rate_hz > 0) || o.message_burst < 1) {
    return "websocket: message_rate_hz must be > 0 and message_burst >= 1";
  }
  if (o.send_queue_messages < 1 || o.send_queue_bytes < 1024) {
    return "websocket: send_queue_messages must be >= 1 and send_queue_bytes >= 1024";
  }
  if (o.socket_send_buffer_bytes < 4096) {
    return "websocket.socket_send_buffer_bytes must be >= 4096";
  }
  if (o.max_objects_per_connection < 0 || o.max_scene_triangles < 1) {
    return "websocket: max_objects_per_connection must be >= 0 and max_scene_triangles >= 1";
  }
  return "";
}

}  // namespace sweptccd
