#include "service/lcm_transport.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <exception>
#include <lcm/lcm-cpp.hpp>
#include <mutex>

#include "core/errors.h"
#include "msgs/text.h"
#include "service/collision_service.h"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

struct LcmTransport::Impl {
  lcm::LCM* lcm = nullptr;
  LcmChannels channels;
  CollisionService* service = nullptr;
  lcm::Subscription* subscription = nullptr;
  lcm::Subscription* object_subscription = nullptr;
  LiveSessionHandler* live = nullptr;
  lcm::Subscription* join_subscription = nullptr;
  lcm::Subscription* leave_subscription = nullptr;
  std::mutex publish_mutex;
  std::atomic<int64_t> received{0};
  std::atomic<int64_t> callback_errors{0};

  TransportSecurity security;

  // Called from inside lcm_handle (a C callback): nothing may escape.
  void HandlePose(const lcm::ReceiveBuffer* rbuf, const std::string& channel) noexcept {
    ++received;
    try {
      Admit(rbuf->data, rbuf->data_size, channel);
    } catch (const std::exception& e) {
      ++callback_errors;
      spdlog::error("LCM pose callback on {}: {}", EscapeForDisplay(channel), e.what());
    } catch (...) {
      ++callback_errors;
      spdlog::error("LCM pose callback on {}: unknown exception", EscapeForDisplay(channel));
    }
  }

  // Bytes, id rule, signature, then decode: nothing is decoded or looked up
  // before its bytes are known to be well formed.
  void Admit(const void* data, size_t size, const std::string& channel) {
    const std::string bytes = ", " + std::to_string(size) + " bytes";
    const std::string problem =
        CheckWire(static_cast<const tracker_pose_t*>(nullptr), data, size, security.limits);
    if (!problem.empty()) return service->OnUndecodable(channel, problem + bytes);
    const std::string id = PeekPoseClientId(data, size);
    if (!IsValidClientId(id)) {
      return service->OnRefused(
          "", Rejection{rejection_code::kBadClientId,
                        "client_id '" + EscapeForDisplay(id) +
                            "' breaks the id rule; send 1-64 characters from A-Z a-z 0-9 _ . -"});
    }
    if (security.signed_mode) {
      // A live id's poses verify under its session key only: the room key
      // cannot speak for a live client.
      std::optional<MacKey> live_key;
      const MacKey* key = service->LiveKey(id, &live_key)
                              ? (live_key ? &*live_key : nullptr)
                              : security.keys.KeyFor(id);
      if (key == nullptr || !VerifyEncoded(data, size, *key)) {
        return service->OnRefused(
            id, Rejection{rejection_code::kBadSignature,
                          key == nullptr ? "no key for client '" + id +
                                               "' and no room key; add it under security.client_keys"
                                         : "the mac of a pose of client '" + id +
                                               "' does not verify; sign with the client's key "
                                               "(--key), or check the key files match"});
      }
    }
    DecodeResult<tracker_pose_t> decoded = DecodeChecked<tracker_pose_t>(data, size, security.limits);
    if (!decoded.ok()) return service->OnUndecodable(channel, decoded.problem + bytes);
    service->OnPose(*decoded.message);
  }

  void HandleObjectPose(const lcm::ReceiveBuffer* rbuf, const std::string& channel) noexcept {
    ++received;
    Guard("object pose", channel, [&] { AdmitObject(rbuf->data, rbuf->data_size, channel); });
  }

  // As Admit: bytes, id rule, the object's key (security.client_keys, else
  // the room key), decode.
  void AdmitObject(const void* data, size_t size, const std::string& channel) {
    const std::string bytes = ", " + std::to_string(size) + " bytes";
    const char* type = "sweptccd.object_pose_t";
    const std::string problem =
        CheckWire(static_cast<const object_pose_t*>(nullptr), data, size, security.limits);
    if (!problem.empty()) return service->OnUndecodable(channel, problem + bytes, type);
    const std::string id = PeekPoseClientId(data, size);  // object_id: the same offset.
    if (!IsValidClientId(id)) {
      return service->OnRefused(
          "", Rejection{rejection_code::kBadClientId,
                        "object_id '" + EscapeForDisplay(id) +
                            "' breaks the id rule; send 1-64 characters from A-Z a-z 0-9 _ . -"});
    }
    if (security.signed_mode) {
      const MacKey* key = security.keys.KeyFor(id);
      if (key == nullptr || !VerifyEncoded(data, size, *key)) {
        return service->OnRefused(
            id, Rejection{rejection_code::kBadSignature,
                          key == nullptr ? "no key for object '" + id +
                                               "' and no room key; add it under objects[].key"
                                         : "the mac of a pose of object '" + id +
                                               "' does not verify; sign with the object's key"});
      }
    }
    DecodeResult<object_pose_t> decoded = DecodeChecked<object_pose_t>(data, size, security.limits);
    if (!decoded.ok()) return service->OnUndecodable(channel, decoded.problem + bytes, type);
    service->OnObjectPose(*decoded.message);
  }

  template <class F>
  void Guard(const char* what, const std::string& channel, F&& f) noexcept {
    try {
      f();
    } catch (const std::exception& e) {
      ++callback_errors;
      spdlog::error("LCM {} callback on {}: {}", what, EscapeForDisplay(channel), e.what());
    } catch (...) {
      ++callback_errors;
      spdlog::error("LCM {} callback on {}: unknown exception", what, EscapeForDisplay(channel));
    }
  }

  void HandleJoin(const lcm::ReceiveBuffer* rbuf, const std::string& channel) noexcept {
    Guard("join", channel, [&] { AdmitJoin(rbuf->data, rbuf->data_size, channel); });
  }
  void HandleLeave(const lcm::ReceiveBuffer* rbuf, const std::string& channel) noexcept {
    Guard("leave", channel, [&] { AdmitLeave(rbuf->data, rbuf->data_size, channel); });
  }

  // The id of a join or leave that CheckWire accepted, or "" after refusing it.
  std::string CheckedId(const void* data, size_t size) {
    const std::string id = PeekPoseClientId(data, size);
    if (IsValidClientId(id)) return id;
    service->OnRefused("", Rejection{rejection_code::kBadClientId,
                                     "client_id '" + EscapeForDisplay(id) +
                                         "' breaks the id rule; send 1-64 characters from "
                                         "A-Z a-z 0-9 _ . -"});
    return "";
  }

  // Bytes, id rule, room-key signature, then decode; the registry queues it.
  void AdmitJoin(const void* data, size_t size, const std::string& channel) {
    const std::string bytes = ", " + std::to_string(size) + " bytes";
    const std::string problem =
        CheckWire(static_cast<const join_request_t*>(nullptr), data, size, security.limits);
    if (!problem.empty()) {
      return service->OnUndecodable(channel, problem + bytes, "sweptccd.join_request_t");
    }
    const std::string id = CheckedId(data, size);
    if (id.empty()) return;
    if (security.signed_mode) {
      const MacKey* key = security.keys.RoomKey();
      if (key == nullptr || !VerifyEncoded(data, size, *key)) {
        return service->OnRefused(
            id, Rejection{rejection_code::kBadSignature,
                          key == nullptr ? "a join of client '" + id +
                                               "' but this daemon has no room key; set "
                                               "security.room_key to take live clients"
                                         : "the mac of a join of client '" + id +
                                               "' does not verify; sign joins with the room key"});
      }
    }
    DecodeResult<join_request_t> decoded =
        DecodeChecked<join_request_t>(data, size, security.limits);
    if (!decoded.ok()) {
      return service->OnUndecodable(channel, decoded.problem + bytes, "sweptccd.join_request_t");
    }
    live->OnJoinRequest(std::move(*decoded.message));
  }

  // Bytes, id rule, the live client's session key, then decode.
  void AdmitLeave(const void* data, size_t size, const std::string& channel) {
    const std::string bytes = ", " + std::to_string(size) + " bytes";
    const std::string problem =
        CheckWire(static_cast<const leave_t*>(nullptr), data, size, security.limits);
    if (!problem.empty()) return service->OnUndecodable(channel, problem + bytes, "sweptccd.leave_t");
    const std::string id = CheckedId(data, size);
    if (id.empty()) return;
    std::optional<MacKey> key;
    if (!service->LiveKey(id, &key)) {
      return service->OnRefused(id, Rejection{rejection_code::kUnknownClient,
                                              "leave of client '" + id +
                                                  "', which is not live; nothing to leave"});
    }
    if (security.signed_mode && (!key || !VerifyEncoded(data, size, *key))) {
      return service->OnRefused(
          id, Rejection{rejection_code::kBadSignature,
                        "the mac of a leave of client '" + id +
                            "' does not verify; sign it with the session key of the join reply"});
    }
    DecodeResult<leave_t> decoded = DecodeChecked<leave_t>(data, size, security.limits);
    if (!decoded.ok()) return service->OnUndecodable(channel, decoded.problem + bytes, "sweptccd.leave_t");
    live->OnLeave(*decoded.message);
  }

  template <typename Msg>
  void Publish(const std::string& channel, const Msg& msg) {
    const std::vector<uint8_t> bytes =
        EncodeSigned(msg, security.signed_mode ? security.keys.ServiceKey() : nullptr);
    std::lock_guard<std::mutex> lock(publish_mutex);
    if (lcm->publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size())) != 0) {
      throw std::runtime_error("lcm publish on " + channel + " failed");
    }
  }
};

LcmTransport::LcmTransport(lcm::LCM* lcm, LcmChannels channels, TransportSecurity security)
    : impl_(std::make_unique<Impl>()) {
  if (lcm == nullptr || !lcm->good()) {
    throw InputError("LCM transport: the LCM instance is not usable (check the LCM URL)");
  }
  if (security.signed_mode && security.keys.ServiceKey() == nullptr) {
    throw InputError("LCM transport: signed mode without a key to sign with; set security.room_key "
                     "or security.service_key (or mode: unsigned for a lab bench)");
  }
  impl_->security = std::move(security);
  impl_->lcm = lcm;
  impl_->channels = std::move(channels);
}

LcmTransport::~LcmTransport() { Unsubscribe(); }

void LcmTransport::Subscribe(CollisionService* service) {
  SWEPTCCD_CHECK(service != nullptr);
  SWEPTCCD_CHECK(impl_->subscription == nullptr);
  impl_->service = service;
  impl_->subscription = impl_->lcm->subscribe(impl_->channels.pose, &Impl::HandlePose, impl_.get());
  if (impl_->subscription == nullptr) {
    throw InputError("LCM transport: cannot subscribe to channel " + impl_->channels.pose);
  }
  impl_->object_subscription =
      impl_->lcm->subscribe(impl_->channels.object_pose, &Impl::HandleObjectPose, impl_.get());
  if (impl_->object_subscription == nullptr) {
    throw InputError("LCM transport: cannot subscribe to channel " + impl_->channels.object_pose);
  }
  impl_->subscription->setQueueCapacity(kLcmQueueCapacity);
  impl_->object_subscription->setQueueCapacity(kLcmQueueCapacity);
}

void LcmTransport::SubscribeLive(LiveSessionHandler* handler) {
  SWEPTCCD_CHECK(handler != nullptr && impl_->service != nullptr);
  SWEPTCCD_CHECK(impl_->join_subscription == nullptr);
  impl_->live = handler;
  impl_->join_subscription =
      impl_->lcm->subscribe(impl_->channels.join, &Impl::HandleJoin, impl_.get());
  impl_->leave_subscription =
      impl_->lcm->subscribe(impl_->channels.leave, &Impl::HandleLeave, impl_.get());
  if (impl_->join_subscription == nullptr || impl_->leave_subscription == nullptr) {
    throw InputError("LCM transport: cannot subscribe to channels " + impl_->channels.join +
                     " and " + impl_->channels.leave);
  }
}

void LcmTransport::Unsubscribe() {
  for (lcm::Subscription** s :
       {&impl_->subscription, &impl_->object_subscription, &impl_->join_subscription,
        &impl_->leave_subscription}) {
    if (*s != nullptr) {
      impl_->lcm->unsubscribe(*s);
      *s = nullptr;
    }
  }
}

void LcmTransport::PublishJoinReply(const join_reply_t& reply) {
  impl_->Publish(impl_->channels.join_reply, reply);
}

void LcmTransport::PublishContact(const contact_event_t& event) {
  impl_->Publish(impl_->channels.contact, event);
}

void LcmTransport::PublishRejection(const rejection_t& rejection) {
  impl_->Publish(impl_->channels.reject, rejection);
}

void LcmTransport::PublishStatus(const status_t& status) {
  impl_->Publish(impl_->channels.status, status);
}

void LcmTransport::PublishSharedContact(const shared_contact_t& event) {
  impl_->Publish(impl_->channels.shared_contact, event);
}

const LcmChannels& LcmTransport::channels() const { return impl_->channels; }
int64_t LcmTransport::messages_received() const { return impl_->received.load(); }
int64_t LcmTransport::callback_errors() const { return impl_->callback_errors.load(); }

}  // namespace sweptccd
