#pragma once
// What the daemon tells its operator, beside the room's own traffic
// (docs/DEPLOY.md): the Prometheus endpoint, systemd's notify protocol and
// watchdog, and the Agones GameServer lifecycle. sweptccd-service builds one
// after its Daemon (scene loaded, backend calibrated), hooks Tick() into the
// daemon's loop, calls Ready() once the loop runs, Stopping() on a stop
// signal.

#include <memory>
#include <string>

#include "service/service_config.h"

namespace sweptccd {

class CollisionService;
class RoomName;

class Operations {
 public:
  /// The Agones SDK sidecar's URL when options.agones.enabled
  /// (AgonesSdk::BaseUrlFromEnvironment: call it before loading the scene, so
  /// a missing AGONES_SDK_HTTP_PORT is refused at once), else "".
  static std::string AgonesUrl(const OpsOptions& options);

  /// Binds the metrics port and reads the systemd environment; throws
  /// InputError (a port taken). `service` and `room` (the room's name: the
  /// metrics' label, set from the GameServer's label under Agones) must
  /// outlive this.
  Operations(const OpsOptions& options, const std::string& agones_url,
             const CollisionService* service, RoomName* room);
  ~Operations();

  /// On the daemon's loop thread, at least every 250 ms: WATCHDOG=1 when due
  /// and a beat for Agones' Health. Test hook: with
  /// SWEPTCCD_TEST_WEDGE_FILE set, the loop is held here while that file
  /// exists (a wedged loop, for tests of the watchdog and Health).
  void Tick();
  /// READY=1 to systemd, Ready to Agones, the metrics endpoint served.
  void Ready();
  /// STOPPING=1; Agones' pings end.
  void Stopping();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd
