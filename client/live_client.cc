#include "sweptccd_client/live_client.h"
#include "sweptccd_client/tracker_pose.h"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <random>

#include "core/errors.h"
#include "msgs/checked_decode.h"
#include "msgs/text.h"
#include "sweptccd/leave_t.hpp"

namespace sweptccd {

namespace {

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

// ---------------------------------------------------------------------------
// DaemonConnection

struct DaemonConnection::Handlers {
  DaemonConnection* self;
  std::atomic<int64_t> undecodable{0};
  std::atomic<int64_t> unverified{0};

  // Byte checks, the id filter, decoding, the mac; nothing escapes into LCM.
  template <class T>
  void Deliver(const lcm::ReceiveBuffer* rbuf, const std::string& channel,
               const Callback<T>& cb, bool filter_by_id) noexcept {
    try {
      if (!cb) return;
      const Options& o = self->options_;
      if (filter_by_id && !o.only_client_id.empty() &&
          PeekPoseClientId(rbuf->data, rbuf->data_size) != o.only_client_id) {
        return;  // Another client's (compared before decoding).
      }
      DecodeResult<T> r = DecodeChecked<T>(rbuf->data, rbuf->data_size, WireLimits{});
      if (!r.ok()) {
        ++undecodable;
        if (self->on_undecodable_) {
          self->on_undecodable_(channel, r.problem + ", " + std::to_string(rbuf->data_size) +
                                             " bytes");
        }
        return;
      }
      const bool verified =
          o.service_key && VerifyEncoded(rbuf->data, rbuf->data_size, *o.service_key);
      if (!verified) {
        ++unverified;
        if (o.service_key && !o.deliver_unverified) return;
      }
      cb(*r.message, verified);
    } catch (...) {
      ++undecodable;  // A callback that throws is the application's bug; never LCM's.
    }
  }
  void Contact(const lcm::ReceiveBuffer* b, const std::string& c) noexcept {
    Deliver<contact_event_t>(b, c, self->on_contact_, true);
  }
  void Rejection(const lcm::ReceiveBuffer* b, const std::string& c) noexcept {
    Deliver<rejection_t>(b, c, self->on_rejection_, true);
  }
  void Status(const lcm::ReceiveBuffer* b, const std::string& c) noexcept {
    Deliver<status_t>(b, c, self->on_status_, false);
  }
  void JoinReply(const lcm::ReceiveBuffer* b, const std::string& c) noexcept {
    Deliver<join_reply_t>(b, c, self->on_join_reply_, false);
  }
  void SharedContact(const lcm::ReceiveBuffer* b, const std::string& c) noexcept {
    Deliver<shared_contact_t>(b, c, self->on_shared_contact_, true);
  }
};

DaemonConnection::DaemonConnection(Options options) : options_(std::move(options)) {
  lcm_ = std::make_unique<lcm::LCM>(options_.lcm_url);
  if (!lcm_->good()) {
    throw InputError("LCM URL '" + options_.lcm_url + "': LCM cannot open it");
  }
  handlers_ = std::make_unique<Handlers>();
  handlers_->self = this;
  const ClientChannels& ch = options_.channels;
  // Every client's events come on one channel: a burst per tick
  // (kLcmQueueCapacity says why LCM's default of 30 loses its tail).
  for (lcm::Subscription* s :
       {lcm_->subscribe(ch.contact, &Handlers::Contact, handlers_.get()),
        lcm_->subscribe(ch.reject, &Handlers::Rejection, handlers_.get()),
        lcm_->subscribe(ch.status, &Handlers::Status, handlers_.get()),
        lcm_->subscribe(ch.join_reply, &Handlers::JoinReply, handlers_.get()),
        lcm_->subscribe(ch.shared_contact, &Handlers::SharedContact, handlers_.get())}) {
    if (s == nullptr) throw InputError("cannot subscribe to the daemon's channels");
    s->setQueueCapacity(kLcmQueueCapacity);
  }
}

DaemonConnection::~DaemonConnection() { Stop(); }

void DaemonConnection::Start() {
  if (thread_.joinable()) return;
  if (pipe2(stop_pipe_, O_CLOEXEC) != 0) {
    throw InputError(std::string("client library: cannot create a pipe: ") + std::strerror(errno));
  }
  thread_ = std::thread([this] {
    for (;;) {
      pollfd fds[2] = {{lcm_->getFileno(), POLLIN, 0}, {stop_pipe_[0], POLLIN, 0}};
      if (poll(fds, 2, -1) < 0) {
        if (errno == EINTR) continue;
        return;
      }
      if (fds[1].revents & POLLIN) return;
      if (fds[0].revents & POLLIN) lcm_->handleTimeout(0);
    }
  });
}

void DaemonConnection::Stop() {
  if (thread_.joinable()) {
    const char quit = 'q';
    while (write(stop_pipe_[1], &quit, 1) < 0 && errno == EINTR) {
    }
    thread_.join();
  }
  for (int& fd : stop_pipe_) {
    if (fd >= 0) close(fd);
    fd = -1;
  }
}

int DaemonConnection::fileno() const { return lcm_->getFileno(); }

bool DaemonConnection::HandleReady(int timeout_ms) {
  return lcm_->handleTimeout(timeout_ms) >= 0;
}

bool DaemonConnection::Publish(const std::string& channel, const std::vector<uint8_t>& bytes) {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  return lcm_->publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size())) == 0;
}

int64_t DaemonConnection::undecodable() const { return handlers_->undecodable.load(); }
int64_t DaemonConnection::unverified() const { return handlers_->unverified.load(); }

// ---------------------------------------------------------------------------
// LiveClient

void FillJoinSkeleton(const Skeleton& skeleton, join_request_t* r) {
  r->num_links = skeleton.num_links();
  r->link_name.clear(), r->parent.clear(), r->a.clear(), r->b.clear(), r->radius.clear();
  for (const Link& l : skeleton.links()) {
    r->link_name.push_back(l.name);
    r->parent.push_back(l.parent);
    r->a.push_back({l.a_L.x(), l.a_L.y(), l.a_L.z()});
    r->b.push_back({l.b_L.x(), l.b_L.y(), l.b_L.z()});
    r->radius.push_back(l.radius);
  }
}

LiveClient::LiveClient(Options options) : options_(std::move(options)) {
  if (!IsValidClientId(options_.client_id)) {
    throw InputError("client id '" + EscapeForDisplay(options_.client_id) +
                     "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
  }
  if (options_.join && !options_.skeleton) {
    throw InputError("client '" + options_.client_id + "': a join needs the skeleton");
  }
  if (options_.join && options_.shared_connection) {
    throw InputError("client '" + options_.client_id + "': a live client needs its own connection");
  }
  if (options_.join && options_.room_key) box_ = NewBoxKeyPair();
  std::random_device rd;
  nonce_ = static_cast<int64_t>((uint64_t{rd()} << 32 | rd()) >> 1);
  if (!options_.join) {
    session_ = options_.session >= 0 ? options_.session : WallUtime();
    joined_ = true;
  }
  if (options_.shared_connection) {
    connection_ = options_.shared_connection;
    return;
  }
  DaemonConnection::Options c;
  c.lcm_url = options_.lcm_url;
  c.channels = options_.channels;
  c.service_key = options_.service_key ? options_.service_key : options_.room_key;
  c.only_client_id = options_.client_id;
  connection_ = std::make_shared<DaemonConnection>(std::move(c));
  connection_->OnJoinReply([this](const join_reply_t& r, bool) {
    if (r.client_id == options_.client_id && r.nonce == nonce_) OnReply(r);
  });
  connection_->OnContact([this](const contact_event_t& e, bool) {
    if (on_contact_) on_contact_(e);
  });
  connection_->OnRejection([this](const rejection_t& r, bool) {
    if (r.reason == "unknown_client" || r.reason == "stale_session") MaybeRejoin(r.reason.c_str());
    if (on_rejection_) on_rejection_(r);
  });
  connection_->OnStatus([this](const status_t& s, bool) {
    bool restarted;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      restarted = joined_ && instance_ != 0 && s.instance != instance_;
    }
    if (restarted) MaybeRejoin("the daemon restarted");
  });
  connection_->Start();
}

LiveClient::~LiveClient() {
  Leave();
  if (!options_.shared_connection) connection_->Stop();
}

void LiveClient::SendJoin() {
  join_request_t r;
  r.utime = WallUtime();
  r.client_id = options_.client_id;
  r.nonce = nonce_;
  std::copy(box_.public_key.begin(), box_.public_key.end(), r.public_key);
  r.motion = options_.motion == MotionModel::kIndependent ? join_request_t::MOTION_INDEPENDENT
                                                          : join_request_t::MOTION_ARTICULATED;
  r.eps_s = options_.eps_s;
  r.delta_m = options_.delta_m;
  FillJoinSkeleton(*options_.skeleton, &r);
  r.num_ignore = static_cast<int32_t>(options_.ignore.size());
  r.ignore = options_.ignore;
  r.num_ignore_entities = static_cast<int32_t>(options_.ignore_entities.size());
  for (const EntityIgnore& rule : options_.ignore_entities) {
    r.ignore_entity_link.push_back(rule.link);
    r.ignore_entity.push_back(rule.entity);
    r.ignore_entity_other_link.push_back(rule.other_link);
  }
  const MacKey* key = options_.room_key ? &*options_.room_key : nullptr;
  connection_->Publish(options_.channels.join, EncodeSigned(r, key));
}

void LiveClient::OnReply(const join_reply_t& reply) {
  JoinResult result;
  result.reason = reply.reason;
  result.message = EscapeForDisplay(reply.message, 400);
  result.session = reply.session;
  result.instance = reply.instance;
  std::optional<MacKey> key;
  if (result.ok() && options_.room_key) {
    key = OpenSealedKey(reply.sealed_key.data(), reply.sealed_key.size(), box_);
    if (!key) {
      result.reason = join_reply_t::REASON_BAD_OPTIONS;
      result.message = "the sealed session key does not open with this client's key pair";
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!left_) {
      if (result.ok()) {
        joined_ = true;
        session_ = result.session;
        instance_ = result.instance;
        session_key_ = std::move(key);
      } else {
        joined_ = false;
      }
    }
    last_reply_ = result;
    ++replies_;
  }
  reply_cv_.notify_all();
  if (on_join_reply_) on_join_reply_(reply);
}

JoinResult LiveClient::Join() {
  if (!options_.join) {
    JoinResult r;
    r.reason = join_reply_t::REASON_ACCEPTED;
    r.session = session();
    return r;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  const int64_t before = replies_;
  lock.unlock();
  SendJoin();
  lock.lock();
  const bool got = reply_cv_.wait_for(
      lock, std::chrono::duration<double>(options_.join_timeout_s),
      [&] { return replies_ > before; });
  if (!got) {
    JoinResult r;
    r.message = "no join reply within " + std::to_string(options_.join_timeout_s) +
                " s; is the daemon running on this LCM URL, and are the keys right?";
    return r;
  }
  return *last_reply_;
}

void LiveClient::MaybeRejoin(const char* why) {
  if (!options_.join || !options_.rejoin) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (left_) return;
    const int64_t now = WallUtime();
    if (now - last_rejoin_us_ < 500'000) return;  // At most two a second.
    last_rejoin_us_ = now;
    ++rejoins_;
  }
  (void)why;
  SendJoin();  // The reply updates the session (OnReply).
}

bool LiveClient::PublishPose(tracker_pose_t pose) {
  const MacKey* key = nullptr;
  std::optional<MacKey> copy;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!joined_ || left_) return false;
    pose.session = session_;
    if (options_.join) {
      copy = session_key_;
    } else {
      copy = options_.client_key ? options_.client_key : options_.room_key;
    }
  }
  if (copy) key = &*copy;
  pose.client_id = options_.client_id;
  return connection_->Publish(options_.channels.pose, EncodeSigned(pose, key));
}

std::string LiveClient::PublishJointFrame(const JointSkeleton& joints, const JointFrame& frame,
                                          int64_t seq) {
  tracker_pose_t m;
  const int joined_links = options_.skeleton ? options_.skeleton->num_links() : -1;
  if (std::string problem = TrackerPoseOfJointFrame(joints, frame, joined_links, seq, &m);
      !problem.empty()) {
    return problem;
  }
  if (!joined()) return "not joined (no session)";
  if (!PublishPose(std::move(m))) return "not published (not joined, or LCM refused)";
  return "";
}

void LiveClient::Leave() {
  leave_t l;
  std::optional<MacKey> key;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (left_) return;
    left_ = true;
    if (!options_.join || !joined_) return;
    joined_ = false;
    l.session = session_;
    key = session_key_;
  }
  l.utime = WallUtime();
  l.client_id = options_.client_id;
  connection_->Publish(options_.channels.leave, EncodeSigned(l, key ? &*key : nullptr));
}

bool LiveClient::joined() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return joined_ && !left_;
}

int64_t LiveClient::session() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return session_;
}

int64_t LiveClient::rejoins() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return rejoins_;
}

}  // namespace sweptccd
