#pragma once
// The LCM adapter of the collision service: decodes tracker poses from the
// pose channel into CollisionService::OnPose and publishes the service's
// messages. lcm headers stay out of here (pimpl); callers pass their own
// lcm::LCM, which lets tests use memq://.

#include <cstdint>
#include <memory>
#include <string>

#include "msgs/channels.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "service/publisher.h"

namespace lcm {
class LCM;
}  // namespace lcm

namespace sweptccd {

class CollisionService;

/// Where the transport hands joins and leaves that passed the byte, id and
/// signature checks (the daemon's live-session registry). Called on the
/// thread that handles LCM; must not block (queue the work).
class LiveSessionHandler {
 public:
  virtual ~LiveSessionHandler() = default;
  virtual void OnJoinRequest(join_request_t request) = 0;
  virtual void OnLeave(const leave_t& leave) = 0;
};

/// Channel names (docs/SERVICE.md).
struct LcmChannels {
  std::string pose = kPoseChannel;        // tracker_pose_t, in.
  std::string contact = kContactChannel;  // contact_event_t, out.
  std::string reject = kRejectChannel;    // rejection_t, out.
  std::string status = kStatusChannel;    // status_t, out.
  std::string join = kJoinChannel;             // join_request_t, in.
  std::string join_reply = kJoinReplyChannel;  // join_reply_t, out.
  std::string leave = kLeaveChannel;           // leave_t, in.
  std::string object_pose = kObjectPoseChannel;        // object_pose_t, in.
  std::string shared_contact = kSharedContactChannel;  // shared_contact_t, out.
};

/// How the transport authenticates what it receives and signs what it sends.
struct TransportSecurity {
  /// true: every pose must carry the HMAC of its client's key (KeyFor), and
  /// everything published is signed with the service key. false (lab bench):
  /// nothing is verified and the mac of what is published is all zero.
  bool signed_mode = true;
  KeyRing keys;
  WireLimits limits;  // Every incoming message is checked against these.
};

/// Publishes on LCM and, once Subscribe()d, feeds the pose channel to a
/// CollisionService.
///
/// Each incoming datagram is, in order: checked against its byte count and
/// the wire limits (CheckWire; else "decode_error"), its client_id checked
/// against the id rule ("bad_client_id"), in signed mode its mac verified
/// with the client's key ("bad_signature"), and only then decoded and handed
/// to CollisionService::OnPose.
///
/// Threading: the Publish* methods are thread-safe (serialised by a mutex).
/// Incoming messages are delivered on the thread that calls
/// lcm->handle()/handleTimeout(). No exception crosses LCM's C callback: a
/// decode failure becomes a "decode_error" rejection; anything else thrown
/// while handling is caught, logged and counted (callback_errors).
class LcmTransport : public Publisher {
 public:
  /// `lcm` must be good() and outlive this object. Throws InputError when
  /// `lcm` is null or not good, or when signed mode has no service key (nor
  /// room key) to sign with.
  LcmTransport(lcm::LCM* lcm, LcmChannels channels = {}, TransportSecurity security = {});
  ~LcmTransport() override;

  LcmTransport(const LcmTransport&) = delete;
  LcmTransport& operator=(const LcmTransport&) = delete;

  /// Subscribes to the pose channel and the object pose channel (object
  /// poses: the same checks, the object's key, then
  /// CollisionService::OnObjectPose) and forwards to `service` (which must
  /// outlive this object, or Unsubscribe() first). Call once.
  void Subscribe(CollisionService* service);
  /// Subscribes to the join and leave channels and forwards them to
  /// `handler` (which must outlive this object, or Unsubscribe() first). A
  /// join must verify under the room key; a leave under the live client's
  /// session key (CollisionService::LiveKey). Call once, after Subscribe().
  void SubscribeLive(LiveSessionHandler* handler);
  /// Stops forwarding poses, joins and leaves. Idempotent.
  void Unsubscribe();
  /// Publishes a join reply (signed with the service key).
  void PublishJoinReply(const join_reply_t& reply);

  void PublishContact(const contact_event_t& event) override;
  void PublishRejection(const rejection_t& rejection) override;
  void PublishStatus(const status_t& status) override;
  void PublishSharedContact(const shared_contact_t& event) override;

  const LcmChannels& channels() const;
  /// Pose messages received on the pose channel (decodable or not).
  int64_t messages_received() const;
  /// Exceptions caught inside the LCM callback.
  int64_t callback_errors() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd
