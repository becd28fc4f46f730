#pragma once
// The LCM adapter of the collision service: decodes tracker poses from the
// pose channel into CollisionService::OnPose and publishes the service's
// messages. lcm headers stay out of here (pimpl); callers pass their own
// lcm::LCM, which lets tests use memq://.

#include <cstdint>
#include <memory>
#include <string>

#include "service/publisher.h"

namespace lcm {
class LCM;
}  // namespace lcm

namespace sweptccd {

class CollisionService;

/// Channel names (docs/SERVICE.md).
struct LcmChannels {
  std::string pose = "SWEPTCCD_POSE";        // tracker_pose_t, in.
  std::string contact = "SWEPTCCD_CONTACT";  // contact_event_t, out.
  std::string reject = "SWEPTCCD_REJECT";    // rejection_t, out.
  std::string status = "SWEPTCCD_STATUS";    // status_t, out.
};

/// Publishes on LCM and, once Subscribe()d, feeds the pose channel to a
/// CollisionService.
///
/// Threading: the Publish* methods are thread-safe (serialised by a mutex).
/// Incoming messages are delivered on the thread that calls
/// lcm->handle()/handleTimeout(). No exception crosses LCM's C callback: a
/// decode failure becomes a "decode_error" rejection; anything else thrown
/// while handling is caught, logged and counted (callback_errors).
class LcmTransport : public Publisher {
 public:
  /// `lcm` must be good() and outlive this object. Throws InputError when
  /// `lcm` is null or not good.
  LcmTransport(lcm::LCM* lcm, LcmChannels channels = {});
  ~LcmTransport() override;

  LcmTransport(const LcmTransport&) = delete;
  LcmTransport& operator=(const LcmTransport&) = delete;

  /// Subscribes to the pose channel and forwards to `service` (which must
  /// outlive this object, or Unsubscribe() first). Call once.
  void Subscribe(CollisionService* service);
  /// Stops forwarding poses. Idempotent.
  void Unsubscribe();

  void PublishContact(const contact_event_t& event) override;
  void PublishRejection(const rejection_t& rejection) override;
  void PublishStatus(const status_t& status) override;

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
