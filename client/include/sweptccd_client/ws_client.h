#pragma once
// The SweptCCD client over the daemon's WebSocket door (docs/WEBSOCKET.md),
// in the shape of the LCM LiveClient (live_client.h): connect, join with a
// skeleton, publish poses, callbacks for contact events, shared contacts,
// rejections and status, leave; on a dropped connection it reconnects with
// backoff (0.25 s doubling to 4 s) and joins again with the same nonce (the
// door hands it the id back under a new session).
//
// Failover (docs/DEPLOY.md, "Failover"): with a room name and a resolver
// (room_resolver.h) every connection asks the resolver for the room's door,
// so a re-connection finds the room's new server. A joined client that hears
// no status of its instance for heartbeat_timeout_s takes the room for dead:
// it closes, re-resolves and re-joins. Events of another daemon instance than
// the joined one are dropped (fenced), and so is a hello of an instance older
// than one already joined. The room is sent (/ws?room=) and hello.room
// checked: a door of another room is refused, never joined. Poses whose pair is not answered yet
// are kept and sent again (same seq and utime) after a re-join, paced within the door's limits; an
// answer for a pair already delivered is dropped. A rejection `unknown_client` (the daemon dropped
// the session) re-joins at once.
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
#include "sweptccd_client/room_resolver.h"

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
    /// Signed rooms: the room key proves joins (and subscriptions); a client
    /// of the daemon's configuration with a key of its own
    /// (security.client_keys) proves its join with that key instead.
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
    /// Room discovery: when set, every connection resolves `room` (host,
    /// port and tls above are then ignored).
    std::shared_ptr<RoomResolver> resolver;
    /// The room this client is for (with or without a resolver): sent as
    /// `/ws?room=ROOM` and checked against hello.room; a door of another
    /// room (409, or another hello.room) is refused and resolved again
    /// (FailoverStats::wrong_rooms). Empty: any door.
    std::string room;
    /// A joined client without a status of its instance for this long takes
    /// the room for dead (0: never); raised to 3 status periods when the
    /// door tells its period (hello.limits.status_period_ms).
    double heartbeat_timeout_s = 3.0;
    double connect_timeout_s = 5.0;   // TCP connect, TLS and upgrade, each.
    double max_backoff_s = 4.0;       // The reconnect backoff's cap.
    size_t max_pending_poses = 4096;  // Unanswered poses kept for a re-join.
  };

  /// What failover did so far.
  struct FailoverStats {
    int64_t heartbeat_losses = 0;  // Rooms taken for dead (no status in time).
    int64_t fenced_events = 0;     // Events of another instance, dropped.
    int64_t fenced_hellos = 0;     // Connections to an older instance, closed.
    int64_t repeated_answers = 0;  // Answers for pairs already delivered, dropped.
    int64_t resent_poses = 0;      // Poses sent again after a re-join.
    int64_t forgotten_poses = 0;   // Pending poses over max_pending_poses.
    int64_t unknown_client_rejoins = 0;
    int64_t resolve_failures = 0;
    int64_t wrong_rooms = 0;  // Doors of another room (409 or hello.room), refused.
    std::string last_error;   // Escaped, one line.
    std::string door;         // The current door's URL ("" before one).
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
  /// Fills client_id and session; queues the pose. False when not joined
  /// yet or left; true while re-joining (the pose waits for the re-join).
  bool PublishPose(tracker_pose_t pose);
  /// Publishes one frame of a tracking runtime's joint poses (OpenXR,
  /// WebXR, VRM; docs/SKELETONS.md) as the link poses of `joints`'
  /// skeleton, which must be the skeleton this client joins with: converts
  /// it (TrackerPoseOfJointFrame, the rule of LiveClient::PublishJointFrame)
  /// and queues it with `seq` as PublishPose does. Returns "" when queued;
  /// else nothing is sent and the one-line reason: the frame's problem, a
  /// link count that is not the joined skeleton's, or not joined / left.
  std::string PublishJointFrame(const JointSkeleton& joints, const JointFrame& frame, int64_t seq);
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
  FailoverStats failover() const;

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
