#pragma once
// The SweptCCD client library for VR applications (docs/SERVICE.md, "Client
// library"): talk to a sweptccd-service daemon over LCM.
//
//   DaemonConnection: one LCM connection that receives what the daemon
//     publishes (contact events, rejections, status, join replies), checks
//     every message's bytes before decoding (DecodeChecked), verifies its mac
//     with the service key and calls the callbacks. `sweptccd monitor` uses it.
//   LiveClient: one avatar. Joins with its skeleton (or, for a client of the
//     daemon's configuration, uses its configured key and a session of its
//     own), publishes signed poses, calls back with its contact events and
//     rejections, re-joins when the daemon restarts or forgot it, and leaves.
//     `sweptccd simulate-tracker` uses it.
//
// Threading: callbacks run on the connection's thread (Start()) or on the
// thread that calls HandleReady(); set them before either. Publishing is
// thread-safe.

#include <array>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "msgs/channels.h"
#include "msgs/signing.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace lcm {
class LCM;
}  // namespace lcm

namespace sweptccd {

/// The daemon's channels (msgs/channels.h; a daemon's configuration may
/// rename them).
struct ClientChannels {
  std::string pose = kPoseChannel;
  std::string contact = kContactChannel;
  std::string reject = kRejectChannel;
  std::string status = kStatusChannel;
  std::string join = kJoinChannel;
  std::string join_reply = kJoinReplyChannel;
  std::string leave = kLeaveChannel;
  std::string object_pose = kObjectPoseChannel;        // Tracked objects' samples (in).
  std::string shared_contact = kSharedContactChannel;  // Shared-world entries, by pair (out).
};

/// Receives and checks what the daemon publishes.
class DaemonConnection {
 public:
  struct Options {
    std::string lcm_url;  // Empty: LCM's default.
    ClientChannels channels;
    /// Verifies every message; none: nothing verifies (verified == false).
    std::optional<MacKey> service_key;
    /// Hand over messages whose mac does not verify too (a monitor shows
    /// them marked); false: they are dropped and counted.
    bool deliver_unverified = false;
    /// Non-empty: only contact events and rejections of this client id
    /// (compared before decoding).
    std::string only_client_id;
  };
  template <class T>
  using Callback = std::function<void(const T& message, bool verified)>;

  /// Opens LCM and subscribes. Throws InputError when the URL cannot be opened.
  explicit DaemonConnection(Options options);
  ~DaemonConnection();  // Stop()s.
  DaemonConnection(const DaemonConnection&) = delete;
  DaemonConnection& operator=(const DaemonConnection&) = delete;

  void OnContact(Callback<contact_event_t> cb) { on_contact_ = std::move(cb); }
  void OnRejection(Callback<rejection_t> cb) { on_rejection_ = std::move(cb); }
  void OnStatus(Callback<status_t> cb) { on_status_ = std::move(cb); }
  void OnJoinReply(Callback<join_reply_t> cb) { on_join_reply_ = std::move(cb); }
  /// The shared world's answers: one message per (pair, batch), each entry a
  /// pair against another client or object (shared_contact_t::entries).
  void OnSharedContact(Callback<shared_contact_t> cb) { on_shared_contact_ = std::move(cb); }
  /// A message that failed its byte checks: the channel and a one-line problem.
  void OnUndecodable(std::function<void(const std::string&, const std::string&)> cb) {
    on_undecodable_ = std::move(cb);
  }

  /// Handles messages on a thread of its own until Stop().
  void Start();
  /// Stops that thread. Idempotent.
  void Stop();
  /// Without Start(): the descriptor to poll, and handling what is ready
  /// (waits at most timeout_ms; 0: not at all). Returns false on an LCM error.
  int fileno() const;
  bool HandleReady(int timeout_ms);

  /// Publishes raw bytes (an encoded, signed message). Thread-safe. False
  /// when LCM refuses.
  bool Publish(const std::string& channel, const std::vector<uint8_t>& bytes);

  const Options& options() const { return options_; }
  int64_t undecodable() const;
  int64_t unverified() const;

 private:
  struct Handlers;
  Options options_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::unique_ptr<Handlers> handlers_;
  Callback<contact_event_t> on_contact_;
  Callback<rejection_t> on_rejection_;
  Callback<status_t> on_status_;
  Callback<join_reply_t> on_join_reply_;
  Callback<shared_contact_t> on_shared_contact_;
  std::function<void(const std::string&, const std::string&)> on_undecodable_;
  std::mutex publish_mutex_;
  std::thread thread_;
  int stop_pipe_[2] = {-1, -1};
};

/// What a join came to: reason is a join_reply_t::REASON_* code, or -1 when
/// no reply came within the timeout.
/// A shared-world filter sent with a join (SPEC 8 "Filters"): this client's
/// `link` never touches `entity` (a client or tracked object id), or only its
/// `other_link` when not empty. Links: a name, an index or "*"; another
/// avatar's link by name only when that avatar is a configured client.
struct EntityIgnore {
  std::string link;
  std::string entity;
  std::string other_link;
};

struct JoinResult {
  int reason = -1;
  std::string message;  // Escaped, one line.
  int64_t session = 0;
  int64_t instance = 0;
  bool ok() const { return reason == join_reply_t::REASON_ACCEPTED; }
};

/// One avatar talking to the daemon.
class LiveClient {
 public:
  struct Options {
    std::string lcm_url;
    ClientChannels channels;
    std::string client_id;  // 1-64 of [A-Za-z0-9_.-].
    /// Signed mode: the room key signs joins (live) or, without client_key,
    /// poses (configured). Neither key: unsigned mode (a lab bench daemon).
    std::optional<MacKey> room_key;
    /// Verifies what the daemon publishes; default: the room key.
    std::optional<MacKey> service_key;

    /// true: a live client (join, then the session and key the reply gives).
    /// false: a client of the daemon's configuration: no join; poses carry
    /// `session` and are signed with client_key (else the room key).
    bool join = true;
    std::optional<MacKey> client_key;
    int64_t session = -1;  // Configured: < 0 takes the wall clock at start (us).
    /// Configured clients only: publish through this connection (several
    /// clients, one LCM instance) and receive nothing (no callbacks).
    std::shared_ptr<DaemonConnection> shared_connection;

    /// The join (live): skeleton, motion, optional filter rules and
    /// tolerances (0: the daemon's).
    std::optional<Skeleton> skeleton;
    MotionModel motion = MotionModel::kArticulated;
    std::vector<std::string> ignore;            // LINK:OBJECT rules.
    std::vector<EntityIgnore> ignore_entities;  // The shared world's filters.
    double eps_s = 0, delta_m = 0;
    double join_timeout_s = 5;
    /// Re-join by itself when the daemon restarts (status_t.instance) or
    /// tells it that it does not know it (unknown_client, stale_session).
    bool rejoin = true;
  };

  /// Opens LCM and starts receiving. Throws InputError (bad id, no skeleton
  /// for a join, LCM cannot open the URL).
  explicit LiveClient(Options options);
  /// Leave()s and stops.
  ~LiveClient();
  LiveClient(const LiveClient&) = delete;
  LiveClient& operator=(const LiveClient&) = delete;

  /// This client's contact events and rejections (verified ones only in
  /// signed mode); set before Join().
  void OnContact(std::function<void(const contact_event_t&)> cb) { on_contact_ = std::move(cb); }
  void OnRejection(std::function<void(const rejection_t&)> cb) { on_rejection_ = std::move(cb); }
  /// Every join reply for this client (the first and each re-join).
  void OnJoinReply(std::function<void(const join_reply_t&)> cb) { on_join_reply_ = std::move(cb); }

  /// Live: sends the join and waits for the reply (join_timeout_s). A
  /// configured client is ready at once (ok). Call once.
  JoinResult Join();
  /// Fills client_id and session, signs and publishes `pose`. False when
  /// not joined (no session yet) or LCM refuses.
  bool PublishPose(tracker_pose_t pose);
  /// Publishes one frame of a tracking runtime's joint poses (OpenXR, WebXR,
  /// VRM; docs/SKELETONS.md) as the link pose of `joints`' skeleton, which
  /// must be the skeleton this client joined with: converts it
  /// (JointSkeleton::Convert, the one rule) and publishes it with `seq` as
  /// PublishPose does. Returns "" when published; else nothing is published
  /// and the one-line reason: the frame's problem (an untracked joint a
  /// link needs, NaN, a wrong joint count, a bone off its length), a link
  /// count that is not the joined skeleton's, not joined, or LCM refusing.
  /// Thread-safe.
  std::string PublishJointFrame(const JointSkeleton& joints, const JointFrame& frame, int64_t seq);
  /// Live: publishes a leave_t and forgets the session. Idempotent.
  void Leave();

  bool joined() const;
  int64_t session() const;
  /// Re-joins sent by the client itself (daemon restart, forgotten).
  int64_t rejoins() const;
  const std::string& client_id() const { return options_.client_id; }

 private:
  void SendJoin();
  void OnReply(const join_reply_t& reply);
  void MaybeRejoin(const char* why);

  Options options_;
  BoxKeyPair box_;
  int64_t nonce_ = 0;
  std::shared_ptr<DaemonConnection> connection_;
  std::function<void(const contact_event_t&)> on_contact_;
  std::function<void(const rejection_t&)> on_rejection_;
  std::function<void(const join_reply_t&)> on_join_reply_;

  mutable std::mutex mutex_;
  std::condition_variable reply_cv_;
  std::optional<JoinResult> last_reply_;
  int64_t replies_ = 0;
  bool joined_ = false;
  bool left_ = false;
  int64_t session_ = 0;
  int64_t instance_ = 0;
  std::optional<MacKey> session_key_;
  int64_t rejoins_ = 0;
  int64_t last_rejoin_us_ = 0;
};

/// Fills a join request's skeleton fields from `skeleton`.
void FillJoinSkeleton(const Skeleton& skeleton, join_request_t* request);

}  // namespace sweptccd
