#include "service/lcm_transport.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <exception>
#include <lcm/lcm-cpp.hpp>
#include <mutex>

#include "core/errors.h"
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

  // Called from inside lcm_handle (a C callback): nothing may escape.
  void HandlePose(const lcm::ReceiveBuffer* rbuf, const std::string& channel) noexcept {
    ++received;
    try {
      tracker_pose_t msg;
      int status = -1;
      std::string problem;
      try {
        status = msg.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size));
        if (status < 0) problem = "wrong fingerprint or truncated message";
      } catch (const std::exception& e) {
        // LCM's generated decoders resize arrays from untrusted lengths.
        problem = std::string("malformed message: ") + e.what();
        status = -1;
      }
      if (status < 0) {
        service->OnUndecodable(channel,
                               problem + ", " + std::to_string(rbuf->data_size) + " bytes");
        return;
      }
      service->OnPose(msg);
    } catch (const std::exception& e) {
      ++callback_errors;
      spdlog::error("LCM pose callback on {}: {}", channel, e.what());
    } catch (...) {
      ++callback_errors;
      spdlog::error("LCM pose callback on {}: unknown exception", channel);
    }
  }

  template <typename Msg>
  void Publish(const std::string& channel, const Msg& msg) {
    std::lock_guard<std::mutex> lock(publish_mutex);
    if (lcm->publish(channel, &msg) != 0) {
      throw std::runtime_error("lcm publish on " + channel + " failed");
    }
  }
};

LcmTransport::LcmTransport(lcm::LCM* lcm, LcmChannels channels) : impl_(std::make_unique<Impl>()) {
  if (lcm == nullptr || !lcm->good()) {
    throw InputError("LCM transport: the LCM instance is not usable (check the LCM URL)");
  }
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
