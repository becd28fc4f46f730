#include "service/ops/ops_options.h"

#include <cmath>

#include "msgs/text.h"
#include "service/ws/door_options.h"

namespace sweptccd {

std::string ValidateOpsOptions(const OpsOptions& o) {
  if (!IsValidClientId(o.room)) {
    return "room: '" + EscapeForDisplay(o.room) +
           "' breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)";
  }
  if (!o.metrics.listen.empty() && !IsLoopbackListen(o.metrics.listen)) {
    return "metrics.listen: '" + EscapeForDisplay(o.metrics.listen) +
           "' is not HOST:PORT on loopback (127.0.0.1, ::1, localhost); the metrics endpoint "
           "is plain HTTP and stays on the host (docs/DEPLOY.md \"Metrics\")";
  }
  const AgonesOptions& a = o.agones;
  if (!(a.health_period_s > 0 && a.health_period_s <= 60)) {
    return "agones.health_period_s: " + std::to_string(a.health_period_s) + " is not in (0, 60]";
  }
  if (!(a.empty_shutdown_s >= 0 && std::isfinite(a.empty_shutdown_s))) {
    return "agones.empty_shutdown_s: " + std::to_string(a.empty_shutdown_s) +
           " is not >= 0 (0: never)";
  }
  return "";
}

}  // namespace sweptccd
