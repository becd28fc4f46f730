#pragma once
// The SweptCCD client over the daemon's WebSocket door (docs/WEBSOCKET.md),
// in the shape of the LCM LiveClient (live_client.h): connect, join with a
// skeleton, publish poses, callbacks for contact events, shared contacts,
// rejections and status, leave; on a dropped connection it reconnects with
// backoff (0.25 s doubling to 4 s) and joins again with the same nonce (the
// door hands it the id back under a new session).
//
// Threading: one I/O thread of its own runs the connection and every
// callback; PublishPose, Leave and Send may be called from any thread.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "msgs/signing.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/live_client.h"

namespace sweptccd {

class WsLiveClient {
 public:
  struct Options {
    std::string host = "127.0.0.1";
    uint16_t port = 8765;
    /// wss://: TLS, the server's certificate checked against ca_file (PEM)
    /// unless verify_peer is false (tests with a self-signed one).
    bool tls = false;
    std::string ca_file;
    bool verify_peer = true;
    std::string origin;  // Sent as Origin when not empty (as a browser).
    std::string client_id;
    /// Signed rooms: the room key proves joins (and subscriptions).
    std::optional<MacKey> room_key;
    /// Join with this skeleton (none: connect without joining, e.g. a viewer).
    std::optional<Skeleton> skeleton;
    MotionModel motion = MotionModel::kArticulated;
    std::vector<std::string> ignore;
    std::vector<EntityIgnore> ignore_entities;
    double eps_s = 0, delta_m = 0;
    double join_timeout_s = 5;
    bool reconnect = true;   // Reconnect and re-join when the connection drops.
    bool subscribe = false;  // Also a viewer: everyone's events (send subscribe).
  };

  /// Throws InputError for a bad client id (when joining). Connects on Join()
  /// or Connect().
  explicit WsLiveClient(Options options);
  /// Leave()s and stops.
  ~WsLiveClient();
  WsLiveClient(const WsLiveClient&) = delete;
  WsLiveClient& operator=(const WsLiveClient&) = delete;

  void OnContact(std::function<void(const contact_event_t&)> cb) { on_contact_ = std::move(cb); }
  void OnSharedContact(std::function<void(const shared_contact_t&)> cb) {
    on_shared_ = std::move(cb);
  }
  void OnRejection(std::function<void(const rejection_t&)> cb) { on_rejection_ = std::move(cb); }
  void OnStatus(std::function<void(const status_t&)> cb) { on_status_ = std::move(cb); }
  void OnJoinReply(std::function<void(const join_reply_t&)> cb) { on_join_reply_ = std::move(cb); }
  /// Error frames: code and one-line message (escape before printing).
  void OnError(std::function<void(const std::string&, const std::string&)> cb) {
    on_error_ = std::move(cb);
  }
  /// Every text message as received (after the typed callback), for tools.
  void OnText(std::function<void(const std::string&)> cb) { on_text_ = std::move(cb); }

  /// Connects, reads hello; with a skeleton, joins and waits for the reply
  /// (join_timeout_s). reason -1: no connection or no reply in time.
  JoinResult Join();
  /// Fills client_id and session; queues the pose. False when not joined.
  bool PublishPose(tracker_pose_t pose);
  /// Sends raw text (tests, attack tools). False when not connected.
  bool Send(const std::string& text);
  /// Sends leave and closes; no reconnect afterwards. Idempotent.
  void Leave();

  bool joined() const;
  int64_t session() const;
  int64_t instance() const;
  /// Connections made after the first (reconnects).
  int64_t reconnects() const;
  /// The current connection's challenge (hello), "" before one.
  std::string challenge() const;
  const std::string& client_id() const;

  struct Impl;

 private:
  std::shared_ptr<Impl> impl_;
  std::function<void(const contact_event_t&)> on_contact_;
  std::function<void(const shared_contact_t&)> on_shared_;
  std::function<void(const rejection_t&)> on_rejection_;
  std::function<void(const status_t&)> on_status_;
  std::function<void(const join_reply_t&)> on_join_reply_;
  std::function<void(const std::string&, const std::string&)> on_error_;
  std::function<void(const std::string&)> on_text_;
};

}  // namespace sweptccd
