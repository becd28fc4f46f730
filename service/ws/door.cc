#include "service/ws/door.h"

#include <openssl/crypto.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <chrono>
#include <map>
#include <optional>
#include <set>
#include <thread>
#include <type_traits>

#include "core/errors.h"
#include "msgs/text.h"
#include "service/collision_service.h"
#include "service/ops/prometheus_text.h"
#include "service/ops/room_name.h"
#include "service/token_bucket.h"
#include "service/ws/client_message.h"
#include "service/ws/lcm_json.h"
#include "service/ws/metrics_token.h"
#include "service/ws/proof.h"
#include "service/ws/send_queue.h"
#include "service/ws/static_files.h"

namespace sweptccd {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using ws::Frame;
using ws::OrderedJson;

namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kSubprotocol = "sweptccd.v1";
constexpr std::chrono::milliseconds kKillAfter{2000};  // A closing peer that never reads.
constexpr std::chrono::milliseconds kRoomPeriod{100};  // Room changes checked this often.

using PlainStream = beast::tcp_stream;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

int64_t SteadyUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(Clock::now().time_since_epoch())
      .count();
}

Frame MakeFrame(const OrderedJson& j) {
  return std::make_shared<const std::string>(
      j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace));
}

Frame ErrorFrame(const std::string& code, const std::string& message, bool fatal) {
  OrderedJson j;
  j["type"] = "error";
  j["code"] = code;
  j["message"] = message;
  j["fatal"] = fatal;
  return MakeFrame(j);
}

// Whether the comma-separated header value lists `token`.
bool ListsToken(std::string_view value, std::string_view token) {
  size_t start = 0;
  while (start <= value.size()) {
    size_t end = value.find(',', start);
    if (end == std::string_view::npos) end = value.size();
    std::string_view t = value.substr(start, end - start);
    while (!t.empty() && (t.front() == ' ' || t.front() == '\t')) t.remove_prefix(1);
    while (!t.empty() && (t.back() == ' ' || t.back() == '\t')) t.remove_suffix(1);
    if (t == token) return true;
    start = end + 1;
  }
  return false;
}

}  // namespace

// A WebSocket connection as the door's registry sees it.
class Conn : public std::enable_shared_from_this<Conn> {
 public:
  virtual ~Conn() = default;
  // Own events: never dropped; an overflow closes with slow_reader.
  virtual void SendOwn(Frame f) = 0;
  // Viewer events of others: dropped when the queue is full.
  virtual void SendOther(Frame f) = 0;
  virtual void SendLatest(const std::string& key, Frame f) = 0;
  virtual void Fatal(const std::string& code, const std::string& message, uint16_t close_code) = 0;

  uint64_t id = 0;
  bool subscribed = false;
  bool joined = false;
  std::string client_id;
  int64_t session = 0;
  int64_t nonce = 0;
};

// Holds one connection's place under the caps; released when the
// connection (handshaking or open) is gone. I/O thread only.
struct ConnSlot {
  WsDoor::Impl* door;
  std::string address;
  ~ConnSlot();
};

struct WsDoor::Impl {
  Impl(WsDoorOptions o, WsDoorContext c) : options(std::move(o)), ctx(std::move(c)) {
    limits = ctx.limits;
    limits.max_message_bytes = options.max_message_bytes;
    idle_timeout = std::chrono::milliseconds(
        options.idle_timeout_ms > 0
            ? options.idle_timeout_ms
            : std::max<int64_t>(ctx.silence_timeout_ms, kDefaultIdleTimeoutMs));
  }

  // I/O thread state (declared before ioc: handlers destroyed with ioc may
  // release slots).
  WsDoorOptions options;
  WsDoorContext ctx;
  WireLimits limits;
  std::chrono::milliseconds idle_timeout{5000};
  std::map<std::string, int> per_address;
  int total = 0;
  std::map<std::string, std::weak_ptr<Conn>> joined;  // Client id -> its connection.
  std::map<uint64_t, std::weak_ptr<Conn>> conns;      // Open WebSocket connections.
  uint64_t next_id = 1;
  int64_t room_version_sent = -1;
  std::atomic<int> connections{0};
  std::atomic<int> websockets{0};
  std::atomic<int> subscribers{0};
  std::atomic<bool> stopping{false};
  bool stopped = false;
  std::mutex stop_mutex;
  uint16_t bound_port = 0;

  net::io_context ioc{1};
  std::optional<ssl::context> tls;
  std::string metrics_token;  // options.metrics_token_path's; empty: no /metrics.
  tcp::acceptor acceptor{ioc};
  net::steady_timer room_timer{ioc};
  std::thread thread;

  void Bind();
  void DoAccept();
  void OnAccept(tcp::socket socket);
  void CheckRoom();
  void Release(const std::string& address) {
    --total;
    --connections;
    auto it = per_address.find(address);
    if (it != per_address.end() && --it->second <= 0) per_address.erase(it);
  }
  bool OriginAllowed(std::string_view origin, std::string_view host) const {
    for (const std::string& o : options.allow_origins) {
      if (origin == o) return true;
    }
    const std::string own = std::string(tls ? "https://" : "http://") + std::string(host);
    return origin == own;
  }
  Frame Hello(const std::string& challenge) const;
  Frame Room() const;
  // Delivers an event of `client_id`: to its connection as its own, to
  // every other subscriber as a viewer's.
  void Route(const std::string& client_id, const Frame& f) {
    std::shared_ptr<Conn> owner;
    if (auto it = joined.find(client_id); it != joined.end()) owner = it->second.lock();
    if (owner) owner->SendOwn(f);
    if (subscribers.load() == 0) return;
    for (auto& [id, w] : conns) {
      auto c = w.lock();
      if (c && c->subscribed && c != owner) c->SendOther(f);
    }
  }
  template <class F>
  void Post(F&& f) {
    if (stopping.load() || websockets.load() == 0) return;
    net::post(ioc, std::forward<F>(f));
  }
};

ConnSlot::~ConnSlot() { door->Release(address); }

namespace {

template <class Stream>
class WsSession : public Conn {
 public:
  WsSession(WsDoor::Impl* door, Stream&& stream, std::unique_ptr<ConnSlot> slot)
      : door_(door),
        ws_(std::move(stream)),
        slot_(std::move(slot)),
        queue_(door->options.send_queue_messages, door->options.send_queue_bytes),
        bucket_(door->options.message_rate_hz, door->options.message_burst),
        idle_timer_(door->ioc),
        kill_timer_(door->ioc) {}

  void Accept(http::request<http::empty_body> req) {
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& res) {
      res.set(http::field::sec_websocket_protocol, kSubprotocol);
      res.set(http::field::server, "sweptccd");
    }));
    ws_.read_message_max(door_->options.max_message_bytes);
    ws_.auto_fragment(false);
    auto self = std::static_pointer_cast<WsSession>(shared_from_this());
    ws_.async_accept(req, [self](beast::error_code ec) { self->OnAccepted(ec); });
  }

  void SendOwn(Frame f) override {
    if (closing_) return;
    if (!queue_.Push(std::move(f))) {
      Fatal("slow_reader",
            "this connection's own events overflowed its send queue (" +
                std::to_string(door_->options.send_queue_messages) + " messages / " +
                std::to_string(door_->options.send_queue_bytes) + " bytes); read faster",
            1008);
      return;
    }
    Flush();
  }
  void SendOther(Frame f) override {
    if (closing_) return;
    if (queue_.Push(std::move(f))) Flush();
  }
  void SendLatest(const std::string& key, Frame f) override {
    if (closing_) return;
    queue_.PushLatest(key, std::move(f));
    Flush();
  }

  void Fatal(const std::string& code, const std::string& message, uint16_t close_code) override {
    if (closing_) return;
    spdlog::info("websocket {} ({}): closing with {}: {}", id, EscapeForDisplay(slot_->address),
                 code, EscapeForDisplay(message, 300));
    queue_.PushForced(ErrorFrame(code, message, true));
    BeginClose(close_code, code);
  }

 private:
  void BeginClose(uint16_t close_code, const std::string& reason) {
    closing_ = true;
    close_code_ = close_code;
    close_reason_ = reason;
    EndSession();
    auto self = std::static_pointer_cast<WsSession>(shared_from_this());
    kill_timer_.expires_after(kKillAfter);
    kill_timer_.async_wait([self](beast::error_code ec) {
      if (!ec) beast::get_lowest_layer(self->ws_).close();
    });
    Flush();
  }

  void OnAccepted(beast::error_code ec) {
    if (ec) {
      spdlog::debug("websocket upgrade from {} failed: {}", EscapeForDisplay(slot_->address),
                    ec.message());
      return;
    }
    beast::get_lowest_layer(ws_).expires_never();
    websocket::stream_base::timeout t{};
    t.handshake_timeout = std::chrono::seconds(2);  // The closing handshake.
    t.idle_timeout = websocket::stream_base::none();
    t.keep_alive_pings = false;
    ws_.set_option(t);
    ws_.control_callback(
        [this](websocket::frame_type, beast::string_view) { last_activity_ = Clock::now(); });
    id = door_->next_id++;
    door_->conns[id] = shared_from_this();
    ++door_->websockets;
    registered_ = true;
    challenge_ = ws::NewChallenge();
    last_activity_ = Clock::now();
    SendOwn(door_->Hello(challenge_));
    Read();
    ArmIdle();
  }

  void ArmIdle() {
    const auto period =
        std::max<std::chrono::milliseconds>(std::chrono::milliseconds(20), door_->idle_timeout / 4);
    idle_timer_.expires_after(period);
    auto self = std::static_pointer_cast<WsSession>(shared_from_this());
    idle_timer_.async_wait([self](beast::error_code ec) {
      if (ec || self->closing_ || self->finished_) return;
      if (Clock::now() - self->last_activity_ > self->door_->idle_timeout) {
        self->Fatal("idle_timeout",
                    "no frame for " + std::to_string(self->door_->idle_timeout.count()) +
                        " ms (idle_timeout_ms); send poses or pings",
                    1008);
        return;
      }
      self->ArmIdle();
    });
  }

  void Read() {
    auto self = std::static_pointer_cast<WsSession>(shared_from_this());
    ws_.async_read(buffer_, [self](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec) {
      if (ec == websocket::error::message_too_big) {
        spdlog::info("websocket {} ({}): message over {} bytes: closed (1009)", id,
                     EscapeForDisplay(slot_->address), door_->options.max_message_bytes);
      }
      Finish();
      return;
    }
    last_activity_ = Clock::now();
    if (closing_) return;
    if (!ws_.got_text()) {
      buffer_.consume(buffer_.size());
      Error("binary_frame", "binary frames are not taken; send JSON text frames");
    } else {
      const std::string text = beast::buffers_to_string(buffer_.data());
      buffer_.consume(buffer_.size());
      Handle(text);
    }
    if (!closing_) Read();
  }

  void Error(const std::string& code, const std::string& message) {
    SendOwn(ErrorFrame(code, message, false));
  }

  void Handle(const std::string& text) {
    if (!bucket_.TryTake(SteadyUs())) {
      const auto now = Clock::now();
      if (now - last_rate_error_ > std::chrono::seconds(1)) {
        last_rate_error_ = now;
        Error("rate_limited", "over " + std::to_string(door_->options.message_rate_hz) +
                                  " messages/s (burst " +
                                  std::to_string(door_->options.message_burst) +
                                  "); messages dropped; send slower");
      }
      return;
    }
    ws::ClientDecodeResult r = ws::DecodeClientMessage(text, door_->limits);
    if (!r.ok()) {
      if (r.code == "too_big") {
        Fatal(r.code, r.problem, 1009);
      } else {
        Error(r.code, r.problem);
      }
      return;
    }
    ws::ClientMessage& m = *r.message;
    switch (m.kind) {
      case ws::ClientMessage::Kind::kJoin:
        OnJoin(m);
        break;
      case ws::ClientMessage::Kind::kPose:
        OnPose(m.pose);
        break;
      case ws::ClientMessage::Kind::kLeave:
        OnLeave(m.leave);
        break;
      case ws::ClientMessage::Kind::kSubscribe:
        OnSubscribe(m.proof);
        break;
      case ws::ClientMessage::Kind::kObjectAttach:
        OnAttach(m.object_id, m.proof);
        break;
      case ws::ClientMessage::Kind::kPing: {
        OrderedJson j;
        j["type"] = "pong";
        j["utime"] = m.ping_utime;
        j["server_utime"] = WallUtime();
        SendOwn(MakeFrame(j));
        break;
      }
      case ws::ClientMessage::Kind::kObjectPose:
        if (!attached_.count(m.object_pose.object_id)) {
          Error("not_attached", "object_pose of '" + EscapeForDisplay(m.object_pose.object_id) +
                                    "', which this connection did not attach; send "
                                    "object_attach first");
          return;
        }
        door_->ctx.service->OnObjectPose(m.object_pose);
        break;
    }
  }

  void Reply(const join_request_t& r, int8_t reason, const std::string& message) {
    join_reply_t reply{};
    reply.utime = WallUtime();
    reply.client_id = IsValidClientId(r.client_id) ? r.client_id : "";
    reply.nonce = r.nonce;
    reply.reason = reason;
    reply.message = message;
    reply.instance = door_->ctx.service->instance();
    reply.silence_timeout_ms = door_->ctx.silence_timeout_ms;
    SendOwn(MakeFrame(ws::ToJson(reply)));
  }

  void OnJoin(ws::ClientMessage& m) {
    const join_request_t& r = m.join;
    if (joined || join_pending_) {
      Error("already_joined", joined
                                  ? "this connection holds session " + std::to_string(session) +
                                        " of '" + client_id + "' already; one join per connection"
                                  : "a join of this connection is being answered");
      return;
    }
    if (door_->ctx.signed_mode) {
      // The id's own key (a configured client's security.client_keys entry),
      // else the room key: the LCM door's rule for poses (KeyRing::KeyFor).
      const MacKey* key = door_->ctx.keys.KeyFor(r.client_id);
      if (key == nullptr) {
        Reply(r, join_reply_t::REASON_JOINS_DISABLED,
              "signed mode without security.room_key: joins cannot be verified; configure a "
              "room key");
        return;
      }
      if (!ws::VerifyProof(*key, ws::ProofKind::kJoin, challenge_, r.client_id, m.proof)) {
        spdlog::info("websocket {} ({}): join of '{}' with a wrong proof", id,
                     EscapeForDisplay(slot_->address), EscapeForDisplay(r.client_id));
        Fatal("bad_proof",
              "the join proof does not verify under the key of '" +
                  EscapeForDisplay(r.client_id, 80) +
                  "' (its own key, else the room key) for this connection's challenge "
                  "(docs/WEBSOCKET.md section 4)",
              1008);
        return;
      }
    }
    if (!IsValidClientId(r.client_id)) {
      Reply(r, join_reply_t::REASON_BAD_CLIENT_ID,
            "client_id '" + EscapeForDisplay(r.client_id) +
                "' breaks the id rule; send 1-64 characters from A-Z a-z 0-9 _ . -");
      return;
    }
    if (r.nonce < 0) {
      Error("bad_message", "join_request.nonce: " + std::to_string(r.nonce) +
                               " is negative; send a random integer in [0, 2^53-1]");
      return;
    }
    // A reconnection of the same client instance takes its id over.
    if (auto it = door_->joined.find(r.client_id); it != door_->joined.end()) {
      if (auto old = it->second.lock(); old && old.get() != this && old->nonce == r.nonce) {
        const int64_t old_session = old->session;
        door_->joined.erase(it);
        old->joined = false;
        old->Fatal("replaced", "a new connection of '" + r.client_id + "' took this session over",
                   1008);
        door_->ctx.service->LeaveLive(r.client_id, old_session);
      }
    }
    join_pending_ = true;
    nonce = r.nonce;
    std::weak_ptr<Conn> weak = shared_from_this();
    WsDoor::Impl* door = door_;
    door_->ctx.submit_join(r, [weak, door](const join_reply_t& reply) {
      net::post(door->ioc, [weak, door, reply] {
        auto self = weak.lock();
        auto* s = static_cast<WsSession*>(self.get());
        if (!s || s->closing_ || s->finished_) {
          if (reply.reason == join_reply_t::REASON_ACCEPTED) {
            door->ctx.service->LeaveLive(reply.client_id, reply.session);
          }
          return;
        }
        s->OnJoinReply(reply);
      });
    });
  }

  void OnJoinReply(const join_reply_t& reply) {
    join_pending_ = false;
    if (reply.reason == join_reply_t::REASON_ACCEPTED) {
      joined = true;
      client_id = reply.client_id;
      session = reply.session;
      door_->joined[client_id] = shared_from_this();
      spdlog::info("websocket {} ({}): '{}' joined, session {}", id,
                   EscapeForDisplay(slot_->address), client_id, session);
    }
    SendOwn(MakeFrame(ws::ToJson(reply)));
  }

  bool CheckSession(const std::string& what, const std::string& id_sent, int64_t session_sent) {
    if (!joined) {
      Error("not_joined", what + " before an accepted join; send join_request first");
      return false;
    }
    if (id_sent != client_id) {
      Error("bad_message", what + ".client_id: '" + EscapeForDisplay(id_sent) +
                               "' is not this connection's client '" + client_id + "'");
      return false;
    }
    if (session_sent != session) {
      Error("bad_message", what + ".session: " + std::to_string(session_sent) +
                               " is not this connection's session " + std::to_string(session));
      return false;
    }
    return true;
  }

  void OnPose(const tracker_pose_t& pose) {
    if (!CheckSession("tracker_pose", pose.client_id, pose.session)) return;
    door_->ctx.service->OnPose(pose);
  }

  void OnLeave(const leave_t& leave) {
    if (!CheckSession("leave", leave.client_id, leave.session)) return;
    spdlog::info("websocket {}: '{}' left (session {})", id, client_id, session);
    BeginClose(1000, "left");  // Ends the session (EndSession).
  }

  void OnSubscribe(const std::string& proof) {
    if (door_->ctx.signed_mode) {
      const MacKey* key = door_->ctx.keys.RoomKey();
      if (key == nullptr ||
          !ws::VerifyProof(*key, ws::ProofKind::kSubscribe, challenge_, "", proof)) {
        Fatal("bad_proof",
              key == nullptr ? "signed mode without security.room_key: subscribers cannot be "
                               "verified"
                             : "the subscribe proof does not verify under the room key",
              1008);
        return;
      }
    }
    if (!subscribed) {
      subscribed = true;
      ++door_->subscribers;
    }
    SendLatest("room", door_->Room());
  }

  void OnAttach(const std::string& object_id, const std::string& proof) {
    OrderedJson j;
    j["type"] = "object_attach_reply";
    j["object_id"] = IsValidClientId(object_id) ? object_id : "";
    const auto& known = door_->ctx.tracked_objects;
    const bool configured = std::find(known.begin(), known.end(), object_id) != known.end();
    if (configured && door_->ctx.signed_mode) {
      const MacKey* key = door_->ctx.keys.KeyFor(object_id);
      if (key == nullptr ||
          !ws::VerifyProof(*key, ws::ProofKind::kObject, challenge_, object_id, proof)) {
        Fatal("bad_proof", "the object_attach proof does not verify under the object's key", 1008);
        return;
      }
    }
    std::string problem;
    if (!configured) {
      problem = "'" + EscapeForDisplay(object_id) + "' is no tracked object of this daemon";
    } else if (!attached_.count(object_id) &&
               static_cast<int>(attached_.size()) >= door_->options.max_objects_per_connection) {
      problem = "this connection has attached " + std::to_string(attached_.size()) +
                " objects, the limit max_objects_per_connection";
    } else {
      attached_.insert(object_id);
    }
    j["ok"] = problem.empty();
    j["message"] = problem;
    SendOwn(MakeFrame(j));
  }

  void Flush() {
    if (writing_ || finished_) return;
    Frame f = queue_.Pop();
    auto self = std::static_pointer_cast<WsSession>(shared_from_this());
    if (!f) {
      if (closing_ && !close_sent_) {
        close_sent_ = true;
        ws_.async_close(
            websocket::close_reason(static_cast<websocket::close_code>(close_code_), close_reason_),
            [self](beast::error_code) { self->Finish(); });
      }
      return;
    }
    writing_ = true;
    ws_.text(true);
    ws_.async_write(net::buffer(*f), [self, f](beast::error_code ec, size_t) {
      self->writing_ = false;
      if (ec) {
        self->Finish();
        return;
      }
      self->Flush();
    });
  }

  // Ends the live session (if any) and leaves the registry's routing.
  void EndSession() {
    if (joined) {
      auto it = door_->joined.find(client_id);
      if (it != door_->joined.end() && it->second.lock().get() == this) door_->joined.erase(it);
      door_->ctx.service->LeaveLive(client_id, session);
      joined = false;
    }
    if (subscribed) {
      subscribed = false;
      --door_->subscribers;
    }
  }

  void Finish() {
    if (finished_) return;
    finished_ = true;
    closing_ = true;
    EndSession();
    if (registered_) {
      door_->conns.erase(id);
      --door_->websockets;
      registered_ = false;
    }
    idle_timer_.cancel();
    kill_timer_.cancel();
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().close(ec);
  }

  WsDoor::Impl* door_;
  websocket::stream<Stream> ws_;
  std::unique_ptr<ConnSlot> slot_;
  beast::flat_buffer buffer_;
  ws::SendQueue queue_;
  TokenBucket bucket_;
  net::steady_timer idle_timer_, kill_timer_;
  std::string challenge_;
  std::set<std::string> attached_;
  Clock::time_point last_activity_{}, last_rate_error_{};
  bool writing_ = false, closing_ = false, close_sent_ = false, finished_ = false;
  bool registered_ = false, join_pending_ = false;
  uint16_t close_code_ = 1000;
  std::string close_reason_;
};

template <class Stream>
class HttpSession : public std::enable_shared_from_this<HttpSession<Stream>> {
 public:
  HttpSession(WsDoor::Impl* door, Stream&& stream, std::unique_ptr<ConnSlot> slot)
      : door_(door), stream_(std::move(stream)), slot_(std::move(slot)) {}

  void Run() {
    auto self = this->shared_from_this();
    if constexpr (std::is_same_v<Stream, TlsStream>) {
      stream_.async_handshake(ssl::stream_base::server, [self](beast::error_code ec) {
        if (ec) {
          spdlog::debug("TLS handshake from {} failed: {}", EscapeForDisplay(self->slot_->address),
                        ec.message());
          return;
        }
        self->Read();
      });
    } else {
      Read();
    }
  }

 private:
  void Read() {
    parser_.emplace();
    parser_->header_limit(8192);
    auto self = this->shared_from_this();
    http::async_read(stream_, buffer_, *parser_,
                     [self](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec) return;  // Timeout, garbage, closed: dropped without an answer.
    http::request<http::empty_body> req = parser_->release();
    if (websocket::is_upgrade(req)) {
      Upgrade(std::move(req));
      return;
    }
    Serve(req);
  }

  void Upgrade(http::request<http::empty_body> req) {
    const std::string_view target(req.target().data(), req.target().size());
    if (target.substr(0, target.find('?')) != "/ws") {
      Text(req, http::status::bad_request, "WebSocket upgrades go to /ws\n");
      return;
    }
    // /ws?room=NAME: a client that asks for a room this door does not hold
    // (the resolver's answer is stale: the room moved) is refused at once.
    if (const std::optional<std::string> asked = RoomAsked(target)) {
      if (!IsValidClientId(*asked)) {
        Text(req, http::status::bad_request,
             "room '" + EscapeForDisplay(*asked, 80) + "' breaks the id rule\n");
        return;
      }
      const std::string held = door_->ctx.room ? door_->ctx.room->Get() : std::string();
      if (*asked != held) {
        Text(req, http::status::conflict,
             "this door holds room '" + held + "', not '" + *asked + "'\n");
        return;
      }
    }
    const auto proto = req[http::field::sec_websocket_protocol];
    if (!ListsToken(std::string_view(proto.data(), proto.size()), kSubprotocol)) {
      Text(req, http::status::bad_request,
           "offer the subprotocol: Sec-WebSocket-Protocol: sweptccd.v1\n");
      return;
    }
    const auto origin = req[http::field::origin];
    const auto host = req[http::field::host];
    if (!origin.empty() && !door_->OriginAllowed(std::string_view(origin.data(), origin.size()),
                                                 std::string_view(host.data(), host.size()))) {
      spdlog::info("websocket from {} refused: Origin '{}' is not allowed (--ws-allow-origin)",
                   EscapeForDisplay(slot_->address),
                   EscapeForDisplay(std::string_view(origin.data(), origin.size())));
      Text(req, http::status::forbidden, "Origin not allowed; add it with --ws-allow-origin\n");
      return;
    }
    if (door_->stopping.load()) {
      Text(req, http::status::service_unavailable, "the daemon is stopping\n");
      return;
    }
    auto session = std::make_shared<WsSession<Stream>>(door_, std::move(stream_), std::move(slot_));
    session->Accept(std::move(req));
  }

  // The value of `room=` in the target's query (the last one given), if any.
  static std::optional<std::string> RoomAsked(std::string_view target) {
    const size_t q = target.find('?');
    if (q == std::string_view::npos) return std::nullopt;
    std::optional<std::string> room;
    std::string_view rest = target.substr(q + 1);
    while (!rest.empty()) {
      const size_t amp = rest.find('&');
      const std::string_view param = rest.substr(0, amp);
      if (param.substr(0, 5) == "room=") room = std::string(param.substr(5));
      rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
    }
    return room;
  }

  void Serve(const http::request<http::empty_body>& req) {
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      Text(req, http::status::method_not_allowed, "GET only\n");
      return;
    }
    const std::string_view full(req.target().data(), req.target().size());
    const std::string_view target = full.substr(0, full.find('?'));
    if (target == "/metrics") {
      Metrics(req);
      return;
    }
    if (target == "/scene.json") {
      Bytes(req, door_->ctx.scene.json, "application/json");
      return;
    }
    if (target.substr(0, 7) == "/scene/" && target.size() > 11 &&
        target.substr(target.size() - 4) == ".bin") {
      const std::string_view n = target.substr(7, target.size() - 11);
      if (n.size() <= 6 && n.find_first_not_of("0123456789") == std::string_view::npos) {
        const size_t index = static_cast<size_t>(std::stoul(std::string(n)));
        if (index < door_->ctx.scene.meshes.size()) {
          Bytes(req, door_->ctx.scene.meshes[index].bin, "application/octet-stream");
          return;
        }
      }
      Text(req, http::status::not_found, "no such scene mesh\n");
      return;
    }
    const std::optional<std::string> file = ws::ResolveViewFile(door_->options.view_dir, target);
    if (!file) {
      Text(req, http::status::not_found, "not found\n");
      return;
    }
    beast::error_code ec;
    http::file_body::value_type body;
    body.open(file->c_str(), beast::file_mode::scan, ec);
    if (ec) {
      Text(req, http::status::not_found, "not found\n");
      return;
    }
    http::response<http::file_body> res{http::status::ok, req.version()};
    const auto size = body.size();
    Headers(&res, ws::ContentTypeOf(*file));
    if (req.method() == http::verb::head) {
      http::response<http::empty_body> head{http::status::ok, req.version()};
      Headers(&head, ws::ContentTypeOf(*file));
      head.content_length(size);
      Write(std::move(head));
      return;
    }
    res.body() = std::move(body);
    res.prepare_payload();
    Write(std::move(res));
  }

  // GET /metrics: only with a configured token, and only for a request that
  // presents it (Authorization: Bearer TOKEN, compared in constant time).
  void Metrics(const http::request<http::empty_body>& req) {
    const std::string& token = door_->metrics_token;
    if (token.empty() || !door_->ctx.metrics) {
      Text(req, http::status::not_found, "not found\n");
      return;
    }
    const auto auth = req[http::field::authorization];
    const std::string want = "Bearer " + token;
    if (auth.size() != want.size() || CRYPTO_memcmp(auth.data(), want.data(), want.size()) != 0) {
      spdlog::info("websocket door: GET /metrics from {} without the metrics token",
                   EscapeForDisplay(slot_->address));
      http::response<http::string_body> res{http::status::unauthorized, req.version()};
      Headers(&res, "text/plain; charset=utf-8");
      res.set(http::field::www_authenticate, "Bearer");
      res.body() = "GET /metrics needs Authorization: Bearer <websocket.metrics_token_file>\n";
      res.prepare_payload();
      Write(std::move(res));
      return;
    }
    Bytes(req, door_->ctx.metrics(), kPrometheusContentType);
  }

  template <class Res>
  void Headers(Res* res, const char* type) {
    res->set(http::field::server, "sweptccd");
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-cache");
    res->set("X-Content-Type-Options", "nosniff");
    res->keep_alive(false);
  }

  void Bytes(const http::request<http::empty_body>& req, const std::string& bytes,
             const char* type) {
    http::response<http::string_body> res{http::status::ok, req.version()};
    Headers(&res, type);
    if (req.method() != http::verb::head) res.body() = bytes;
    res.content_length(bytes.size());
    Write(std::move(res));
  }

  void Text(const http::request<http::empty_body>& req, http::status status,
            const std::string& text) {
    http::response<http::string_body> res{status, req.version()};
    Headers(&res, "text/plain; charset=utf-8");
    res.body() = text;
    res.prepare_payload();
    Write(std::move(res));
  }

  template <class Body>
  void Write(http::response<Body>&& res) {
    auto sp = std::make_shared<http::response<Body>>(std::move(res));
    beast::get_lowest_layer(stream_).expires_after(std::chrono::seconds(30));
    auto self = this->shared_from_this();
    http::async_write(stream_, *sp, [self, sp](beast::error_code, size_t) {
      beast::error_code ec;
      beast::get_lowest_layer(self->stream_).socket().shutdown(tcp::socket::shutdown_send, ec);
    });
  }

  WsDoor::Impl* door_;
  Stream stream_;
  std::unique_ptr<ConnSlot> slot_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::empty_body>> parser_;
};

}  // namespace

Frame WsDoor::Impl::Hello(const std::string& challenge) const {
  OrderedJson j;
  j["type"] = "hello";
  j["protocol"] = 1;
  j["instance"] = ctx.service->instance();
  j["security"] = ctx.signed_mode ? "signed" : "unsigned";
  j["challenge"] = challenge;
  j["server_utime"] = WallUtime();
  j["shared_world"] = ctx.shared_world;
  if (ctx.room) j["room"] = ctx.room->Get();
  OrderedJson l;
  l["max_message_bytes"] = options.max_message_bytes;
  l["max_links"] = limits.max_links;
  l["max_join_links"] = limits.max_join_links;
  l["max_ignore_rules"] = limits.max_ignore_rules;
  l["max_id_bytes"] = limits.max_id_bytes;
  l["max_text_bytes"] = limits.max_text_bytes;
  l["message_rate_hz"] = options.message_rate_hz;
  l["message_burst"] = options.message_burst;
  l["max_pose_rate_hz"] = ctx.max_pose_rate_hz;
  l["pose_burst"] = ctx.pose_burst;
  l["silence_timeout_ms"] = ctx.silence_timeout_ms;
  l["status_period_ms"] = ctx.status_period_ms;
  l["idle_timeout_ms"] = idle_timeout.count();
  l["handshake_timeout_ms"] = options.handshake_timeout_ms;
  l["max_connections"] = options.max_connections;
  l["max_connections_per_address"] = options.max_connections_per_address;
  l["send_queue_messages"] = options.send_queue_messages;
  l["send_queue_bytes"] = options.send_queue_bytes;
  l["max_objects_per_connection"] = options.max_objects_per_connection;
  j["limits"] = std::move(l);
  return MakeFrame(j);
}

Frame WsDoor::Impl::Room() const {
  OrderedJson j;
  j["type"] = "room";
  j["utime"] = WallUtime();
  j["instance"] = ctx.service->instance();
  j["shared_world"] = ctx.shared_world;
  OrderedJson clients = OrderedJson::array();
  for (const RoomClient& c : ctx.service->RoomClients()) {
    OrderedJson e;
    e["client_id"] = c.client_id;
    e["live"] = c.live;
    e["door"] = !c.live ? "config" : joined.count(c.client_id) ? "websocket" : "lcm";
    e["motion"] = c.motion == MotionModel::kIndependent ? 1 : 0;
    OrderedJson names = OrderedJson::array(), parents = OrderedJson::array(),
                a = OrderedJson::array(), b = OrderedJson::array(), radius = OrderedJson::array();
    for (const Link& l : c.skeleton->links()) {
      names.push_back(l.name);
      parents.push_back(l.parent);
      a.push_back({l.a_L.x(), l.a_L.y(), l.a_L.z()});
      b.push_back({l.b_L.x(), l.b_L.y(), l.b_L.z()});
      radius.push_back(l.radius);
    }
    e["link_name"] = std::move(names);
    e["parent"] = std::move(parents);
    e["a"] = std::move(a);
    e["b"] = std::move(b);
    e["radius"] = std::move(radius);
    clients.push_back(std::move(e));
  }
  j["clients"] = std::move(clients);
  OrderedJson objects = OrderedJson::array(), env = OrderedJson::array();
  for (size_t i = 0; i < ctx.scene.meshes.size(); ++i) {
    const ws::SceneMesh& m = ctx.scene.meshes[i];
    if (m.kind == "object") {
      objects.push_back({{"object_id", m.object_id}, {"scene_index", i}});
    } else {
      env.push_back(m.name);
    }
  }
  j["objects"] = std::move(objects);
  j["environment"] = std::move(env);
  return MakeFrame(j);
}

void WsDoor::Impl::Bind() {
  const std::string& listen = options.listen;
  const size_t colon = listen.rfind(':');
  std::string host = listen.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[') host = host.substr(1, host.size() - 2);
  if (host == "localhost") host = "127.0.0.1";
  const int port = std::stoi(listen.substr(colon + 1));
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(host, ec);
  if (ec) {
    throw InputError("--ws-listen '" + listen + "': '" + host +
                     "' is not an IP address; give e.g. 127.0.0.1:8765 or 0.0.0.0:8765");
  }
  const tcp::endpoint endpoint(address, static_cast<uint16_t>(port));
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    throw InputError("--ws-listen '" + listen + "': cannot listen: " + ec.message() +
                     "; pick a free port or another address");
  }
  bound_port = acceptor.local_endpoint().port();
}

void WsDoor::Impl::DoAccept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (!stopping.load() && ec != net::error::operation_aborted) DoAccept();
      return;
    }
    OnAccept(std::move(socket));
    DoAccept();
  });
}

void WsDoor::Impl::OnAccept(tcp::socket socket) {
  beast::error_code ec;
  const tcp::endpoint remote = socket.remote_endpoint(ec);
  if (ec) return;
  const std::string address = remote.address().to_string();
  const int here = per_address.count(address) ? per_address[address] : 0;
  if (stopping.load() || total >= options.max_connections ||
      here >= options.max_connections_per_address) {
    spdlog::debug("connection from {} closed at once: {} open ({} from it); caps {} / {}", address,
                  total, here, options.max_connections, options.max_connections_per_address);
    socket.close(ec);
    return;
  }
  ++total;
  ++connections;
  ++per_address[address];
  auto slot = std::unique_ptr<ConnSlot>(new ConnSlot{this, address});
  socket.set_option(tcp::no_delay(true), ec);
  socket.set_option(net::socket_base::send_buffer_size(options.socket_send_buffer_bytes), ec);
  PlainStream stream(std::move(socket));
  stream.expires_after(std::chrono::milliseconds(options.handshake_timeout_ms));
  if (tls) {
    std::make_shared<HttpSession<TlsStream>>(this, TlsStream(std::move(stream), *tls),
                                             std::move(slot))
        ->Run();
  } else {
    std::make_shared<HttpSession<PlainStream>>(this, std::move(stream), std::move(slot))->Run();
  }
}

void WsDoor::Impl::CheckRoom() {
  room_timer.expires_after(kRoomPeriod);
  room_timer.async_wait([this](beast::error_code ec) {
    if (ec || stopping.load()) return;
    const int64_t version = ctx.service->room_version();
    if (version != room_version_sent && subscribers.load() > 0) {
      room_version_sent = version;
      const Frame f = Room();
      for (auto& [id, w] : conns) {
        if (auto c = w.lock(); c && c->subscribed) c->SendLatest("room", f);
      }
    }
    CheckRoom();
  });
}

WsDoor::WsDoor(WsDoorOptions options, WsDoorContext context)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(context))) {
  const WsDoorOptions& o = impl_->options;
  if (const std::string problem = ValidateWsDoorOptions(o); !problem.empty()) {
    throw InputError(problem);
  }
  if (o.cert_path.empty() && impl_->ctx.signed_mode && !IsLoopbackListen(o.listen)) {
    throw InputError("--ws-listen '" + o.listen +
                     "': plain ws:// on a non-loopback address in signed mode; give --ws-cert "
                     "FILE --ws-key FILE (PEM) for wss://, or listen on 127.0.0.1");
  }
  if (!o.cert_path.empty()) {
    impl_->tls.emplace(ssl::context::tls_server);
    auto& t = *impl_->tls;
    t.set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 |
                  ssl::context::no_sslv3 | ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 |
                  ssl::context::single_dh_use);
    beast::error_code ec;
    t.use_certificate_chain_file(o.cert_path, ec);
    if (ec) {
      throw InputError("--ws-cert '" + o.cert_path + "': " + ec.message() +
                       "; give a PEM certificate chain");
    }
    t.use_private_key_file(o.key_path, ssl::context::pem, ec);
    if (ec) {
      throw InputError("--ws-key '" + o.key_path + "': " + ec.message() +
                       "; give the PEM private key of --ws-cert");
    }
  }
  if (!o.metrics_token_path.empty())
    impl_->metrics_token = ws::LoadMetricsToken(o.metrics_token_path);
  impl_->Bind();
}

WsDoor::~WsDoor() { Stop(); }

void WsDoor::Start() {
  impl_->DoAccept();
  impl_->CheckRoom();
  impl_->thread = std::thread([impl = impl_.get()] { impl->ioc.run(); });
  spdlog::info("websocket door on {}://{} (port {}), view files from '{}'",
               impl_->tls ? "wss" : "ws", impl_->options.listen, impl_->bound_port,
               impl_->options.view_dir);
}

void WsDoor::Stop() {
  std::lock_guard<std::mutex> lock(impl_->stop_mutex);
  if (impl_->stopped) return;
  impl_->stopped = true;
  impl_->stopping = true;
  Impl* impl = impl_.get();
  net::post(impl->ioc, [impl] {
    beast::error_code ec;
    impl->acceptor.close(ec);
    impl->room_timer.cancel();
    std::vector<std::shared_ptr<Conn>> open;
    for (auto& [id, w] : impl->conns) {
      if (auto c = w.lock()) open.push_back(c);
    }
    for (auto& c : open) c->Fatal("shutting_down", "the daemon stops", 1001);
  });
  if (impl->thread.joinable()) {
    const auto deadline = Clock::now() + std::chrono::seconds(1);
    while (impl->websockets.load() > 0 && Clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    impl->ioc.stop();
    impl->thread.join();
  }
}

uint16_t WsDoor::port() const { return impl_->bound_port; }

int WsDoor::connections() const { return impl_->connections.load(); }

// Every event a client may act on carries the daemon run (its epoch,
// docs/WEBSOCKET.md): a client fences events of an older instance.
template <class Event>
Frame EpochFrame(WsDoor::Impl* impl, const Event& e) {
  OrderedJson j = ws::ToJson(e);
  j["instance"] = impl->ctx.service->instance();
  return MakeFrame(j);
}

void WsDoor::PublishContact(const contact_event_t& event) {
  auto e = std::make_shared<const contact_event_t>(event);
  impl_->Post([impl = impl_.get(), e] { impl->Route(e->client_id, EpochFrame(impl, *e)); });
}

void WsDoor::PublishSharedContact(const shared_contact_t& event) {
  auto e = std::make_shared<const shared_contact_t>(event);
  impl_->Post([impl = impl_.get(), e] { impl->Route(e->client_id, EpochFrame(impl, *e)); });
}

void WsDoor::PublishRejection(const rejection_t& rejection) {
  auto e = std::make_shared<const rejection_t>(rejection);
  impl_->Post([impl = impl_.get(), e] { impl->Route(e->client_id, EpochFrame(impl, *e)); });
}

void WsDoor::PublishStatus(const status_t& status) {
  auto e = std::make_shared<const status_t>(status);
  impl_->Post([impl = impl_.get(), e] {
    OrderedJson j = ws::ToJson(*e);
    if (impl->ctx.room) j["room"] = impl->ctx.room->Get();
    const Frame f = MakeFrame(j);
    for (auto& [id, w] : impl->conns) {
      if (auto c = w.lock(); c && (c->joined || c->subscribed)) c->SendLatest("status", f);
    }
  });
}

void WsDoor::ForwardPose(const tracker_pose_t& pose) {
  if (impl_->subscribers.load() == 0) return;
  auto e = std::make_shared<const tracker_pose_t>(pose);
  impl_->Post([impl = impl_.get(), e] {
    const Frame f = EpochFrame(impl, *e);
    const std::string key = "pose:" + e->client_id;
    for (auto& [id, w] : impl->conns) {
      if (auto c = w.lock(); c && c->subscribed) c->SendLatest(key, f);
    }
  });
}

void WsDoor::ForwardObjectPose(const object_pose_t& pose) {
  if (impl_->subscribers.load() == 0) return;
  auto e = std::make_shared<const object_pose_t>(pose);
  impl_->Post([impl = impl_.get(), e] {
    const Frame f = EpochFrame(impl, *e);
    const std::string key = "object:" + e->object_id;
    for (auto& [id, w] : impl->conns) {
      if (auto c = w.lock(); c && c->subscribed) c->SendLatest(key, f);
    }
  });
}

}  // namespace sweptccd
