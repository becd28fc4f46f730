#pragma once
// The daemon's Publisher: every message goes to the LCM transport and, when
// the WebSocket door is open, to the door as well (one room, many doors).

#include <atomic>

#include "service/publisher.h"

namespace sweptccd {

/// Thread-safe as its targets are. The door may be attached after
/// construction (it needs the service, which needs this publisher) and
/// detached before it is destroyed.
class FanoutPublisher : public Publisher {
 public:
  explicit FanoutPublisher(Publisher* first) : first_(first) {}
  void SetSecond(Publisher* second) { second_.store(second); }

  void PublishContact(const contact_event_t& e) override {
    first_->PublishContact(e);
    if (Publisher* s = second_.load()) s->PublishContact(e);
  }
  void PublishRejection(const rejection_t& r) override {
    first_->PublishRejection(r);
    if (Publisher* s = second_.load()) s->PublishRejection(r);
  }
  void PublishStatus(const status_t& st) override {
    first_->PublishStatus(st);
    if (Publisher* s = second_.load()) s->PublishStatus(st);
  }
  void PublishSharedContact(const shared_contact_t& e) override {
    first_->PublishSharedContact(e);
    if (Publisher* s = second_.load()) s->PublishSharedContact(e);
  }
  void ForwardPose(const tracker_pose_t& p) override {
    first_->ForwardPose(p);
    if (Publisher* s = second_.load()) s->ForwardPose(p);
  }
  void ForwardObjectPose(const object_pose_t& p) override {
    first_->ForwardObjectPose(p);
    if (Publisher* s = second_.load()) s->ForwardObjectPose(p);
  }

 private:
  Publisher* first_;
  std::atomic<Publisher*> second_{nullptr};
};

}  // namespace sweptccd
