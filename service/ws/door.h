#pragma once
// The daemon's WebSocket door (docs/WEBSOCKET.md): one listening socket
// (TLS or, on loopback / unsigned, plain) serving the live view's files, the
// scene, and `/ws`, where browsers and native clients join the SAME room as
// LCM clients: joins go through the daemon's join thread (`submit_join`),
// poses into CollisionService::OnPose, and the service's messages come back
// through this Publisher (the daemon fans out to LCM and here).
//
// Threading: one I/O thread owns every socket and connection. The
// Publisher methods may be called from any thread: they copy the message
// and post it to the I/O thread, never wait on a socket.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "service/publisher.h"
#include "service/ws/door_options.h"
#include "service/ws/scene.h"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"

namespace sweptccd {

class CollisionService;
class RoomName;

/// What the door needs of the daemon.
struct WsDoorContext {
  CollisionService* service = nullptr;  // Outlives the door.
  /// The room's name, told in hello and status (may change once Agones
  /// labels the GameServer); outlives the door. Null: not told.
  const RoomName* room = nullptr;
  bool signed_mode = true;
  KeyRing keys;       // The room's keys (room key: joins, subscribers; objects' keys).
  WireLimits limits;  // Field limits (max_links, max_join_links, strings...).
  int64_t silence_timeout_ms = 5000;
  int64_t status_period_ms = 1000;  // Told in hello: clients size their heartbeat by it.
  double max_pose_rate_hz = 240;
  int pose_burst = 16;
  bool shared_world = false;
  std::vector<std::string> tracked_objects;  // Configured tracked object ids.
  ws::Scene scene;                           // Built once at start (ws/scene.h).
  /// Queues a join on the daemon's join thread (the LCM door's path): in
  /// signed mode its session key is a fresh random key kept by the
  /// service and told nobody. `reply` is called once, on any thread.
  std::function<void(join_request_t, std::function<void(const join_reply_t&)>)> submit_join;
  /// The Prometheus text of the room (service/ops/prometheus_text.h), for
  /// GET /metrics with the bearer token (options.metrics_token_path); called
  /// on the door's I/O thread. Empty: /metrics is not served.
  std::function<std::string()> metrics;
};

class WsDoor : public Publisher {
 public:
  /// Binds the listening socket and loads the TLS files. Throws InputError
  /// with one line naming the setting and the fix (bad address, port in
  /// use, unreadable PEM, plain ws:// on a non-loopback address in signed
  /// mode).
  WsDoor(WsDoorOptions options, WsDoorContext context);
  /// Stop()s.
  ~WsDoor() override;
  WsDoor(const WsDoor&) = delete;
  WsDoor& operator=(const WsDoor&) = delete;

  /// Starts the I/O thread (accepting).
  void Start();
  /// Sends `shutting_down` to every connection, closes them (1 s at most),
  /// stops the I/O thread. Idempotent.
  void Stop();
  /// The bound port (a listen port 0 picks one).
  uint16_t port() const;
  /// Open connections (handshaking ones included).
  int connections() const;

  void PublishContact(const contact_event_t& event) override;
  void PublishRejection(const rejection_t& rejection) override;
  void PublishStatus(const status_t& status) override;
  void PublishSharedContact(const shared_contact_t& event) override;
  void ForwardPose(const tracker_pose_t& pose) override;
  void ForwardObjectPose(const object_pose_t& pose) override;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd
