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
      const MacKey* key = security.keys.KeyFor(id);
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
}

void LcmTransport::Unsubscribe() {
  if (impl_->subscription != nullptr) {
    impl_->lcm->unsubscribe(impl_->subscription);
    impl_->subscription = nullptr;
  }
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

const LcmChannels& LcmTransport::channels() const { return impl_->channels; }
int64_t LcmTransport::messages_received() const { return impl_->received.load(); }
int64_t LcmTransport::callback_errors() const { return impl_->callback_errors.load(); }

}  // namespace sweptccd
