#pragma once
// What an operator runs the daemon with beyond its room (docs/DEPLOY.md):
// the room's name in metrics, the Prometheus endpoint, and the Agones SDK
// sidecar. YAML keys `room`, `metrics:` and `agones:` (deploy/sweptccd.yaml);
// flags --room, --metrics-listen, --agones.

#include <string>

namespace sweptccd {

struct MetricsOptions {
  /// HOST:PORT of the Prometheus endpoint (GET /metrics), loopback only
  /// (plain HTTP never leaves the host); empty: off.
  std::string listen;
};

struct AgonesOptions {
  bool enabled = false;          // Off by default: the daemon is no GameServer.
  double health_period_s = 2.0;  // Health pings from the loop, seconds, in (0, 60].
  /// Shutdown after the room has had no live client for this long, seconds;
  /// 0: never (the fleet's allocator ends the room).
  double empty_shutdown_s = 300;
};

struct OpsOptions {
  std::string room = "sweptccd";  // The `room` label of every metric; the id rule.
  MetricsOptions metrics;
  AgonesOptions agones;
};

/// The problem with `o` (empty when valid): the room name's id rule, a
/// metrics address that is not HOST:PORT on loopback, Agones periods.
std::string ValidateOpsOptions(const OpsOptions& o);

}  // namespace sweptccd
