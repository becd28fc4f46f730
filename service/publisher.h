#pragma once
// Where the collision service sends its messages. The LCM adapter implements
// it; tests capture.

#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

/// Output of the collision service. Implementations must be thread-safe:
/// workers call PublishContact concurrently (for different clients), and the
/// thread that calls CollisionService::OnPose calls PublishRejection. Per
/// client, contact events arrive in pair order. An exception thrown here is
/// caught by the service, logged and counted (publish_errors); it never stops
/// a worker.
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual void PublishContact(const contact_event_t& event) = 0;
  virtual void PublishRejection(const rejection_t& rejection) = 0;
  virtual void PublishStatus(const status_t& status) = 0;
  /// The shared part of a pair against one other entity (docs/SERVICE.md
  /// "Shared world"), from worker threads, after that pair's contact event.
  /// Default: dropped (a publisher that does not serve the shared world).
  virtual void PublishSharedContact(const shared_contact_t& /*event*/) {}
  /// A pose the service took (accepted: not rejected, not shed by a rate
  /// limit), on the thread that called OnPose, after its lock: for viewers
  /// (the WebSocket door forwards it, latest-wins). Must not block. Default:
  /// dropped.
  virtual void ForwardPose(const tracker_pose_t& /*pose*/) {}
  /// Likewise a tracked object's pose the service took.
  virtual void ForwardObjectPose(const object_pose_t& /*pose*/) {}
};

}  // namespace sweptccd
