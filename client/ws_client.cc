#include "sweptccd_client/ws_client.h"

#include <atomic>
#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "core/errors.h"
#include "msgs/text.h"
#include "service/ws/json_fields.h"
#include "service/ws/lcm_json.h"
#include "service/ws/proof.h"
#include "sweptccd_client/pair_ledger.h"
#include "sweptccd_client/tracker_pose.h"

namespace sweptccd {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;

namespace {

using Clock = std::chrono::steady_clock;
using PlainWs = websocket::stream<beast::tcp_stream>;
using TlsWs = websocket::stream<beast::ssl_stream<beast::tcp_stream>>;

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

struct WsLiveClient::Impl : std::enable_shared_from_this<WsLiveClient::Impl> {
  Impl(WsLiveClient* o, Options opt)
      : owner(o), options(std::move(opt)), ledger(options.max_pending_poses) {
    std::random_device rd;
    nonce = static_cast<int64_t>((uint64_t{rd()} << 32 | rd()) & ((uint64_t{1} << 53) - 1));
    if (options.tls && !options.resolver) MakeTls();
  }

  void MakeTls() {
    {
      tls.emplace(ssl::context::tls_client);
      if (options.verify_peer) {
        tls->set_verify_mode(ssl::verify_peer);
        if (!options.ca_file.empty()) {
          tls->load_verify_file(options.ca_file);
        } else {
          tls->set_default_verify_paths();
        }
      } else {
        tls->set_verify_mode(ssl::verify_none);
      }
    }
  }

  WsLiveClient* owner;
  Options options;
  int64_t nonce = 0;
  net::io_context ioc{1};
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work{
      net::make_work_guard(ioc)};
  std::optional<ssl::context> tls;
  std::unique_ptr<PlainWs> plain;
  std::unique_ptr<TlsWs> secure;
  beast::flat_buffer buffer;
  std::deque<std::string> out;
  bool writing = false;
  net::steady_timer backoff_timer{ioc};
  std::chrono::milliseconds backoff{250};
  std::thread thread;

  mutable std::mutex mutex;
  std::condition_variable cv;
  bool connected = false;
  bool is_joined = false;
  bool left = false;
  bool stopping = false;
  int64_t session = 0;
  int64_t instance = 0;
  int64_t replies = 0;
  int64_t connections = 0;
  int64_t failures = 0;  // Connections that failed or dropped (Join without reconnect stops).
  std::optional<JoinResult> last_reply;
  std::string challenge;
  uint64_t generation = 0;  // Bumped by every connection: stale handlers ignore themselves.

  // Failover (guarded by mutex unless said otherwise).
  PairLedger ledger;
  std::set<std::pair<int64_t, std::string>> shared_seen;  // (seq1, entity) delivered.
  bool ever_joined = false;
  int64_t max_instance = 0;  // The newest instance joined: older hellos are fenced.
  FailoverStats stats;
  Clock::time_point last_status;  // I/O thread.
  net::steady_timer heartbeat_timer{ioc};
  // Re-sent poses (I/O thread): lock-step (the next one once the pair of
  // the previous one is answered, or after kLockstepWait), so the service's
  // latest-wins never merges them into one pair, and within the door's rate
  // limits.
  struct OutPose {
    int64_t seq;
    bool anchor;  // The first of a re-join: it forms no pair.
    std::string text;
  };
  std::deque<OutPose> pose_out;
  int64_t awaiting = -1;  // seq of the re-sent pose whose pair is awaited.
  double tokens = 0, pose_rate = 100, pose_burst = 8;
  Clock::time_point tokens_at;
  bool pump_armed = false;
  net::steady_timer pump_timer{ioc};
  net::steady_timer lockstep_timer{ioc};
  static constexpr std::chrono::milliseconds kLockstepWait{250};

  template <class F>
  void With(F&& f) {
    if (secure) {
      f(*secure);
    } else if (plain) {
      f(*plain);
    }
  }

  // I/O thread: a fresh connection, hello, join, subscribe. False on failure.
  bool Connect() {
    try {
      std::string host = options.host;
      uint16_t port = options.port;
      bool use_tls = options.tls;
      if (options.resolver) {
        DoorAddress d;
        try {
          d = options.resolver->Resolve(options.room);
        } catch (const RoomError& e) {
          std::lock_guard<std::mutex> lock(mutex);
          ++stats.resolve_failures;
          throw;
        }
        host = d.host;
        port = d.port;
        use_tls = d.tls;
        if (use_tls && !tls) MakeTls();
        std::lock_guard<std::mutex> lock(mutex);
        stats.door = d.Url();
      } else {
        std::lock_guard<std::mutex> lock(mutex);
        stats.door = DoorAddress{host, port, use_tls, "static"}.Url();
      }
      const auto timeout = std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(options.connect_timeout_s));
      tcp::resolver resolver(ioc);
      const auto endpoints = resolver.resolve(host, std::to_string(port));
      beast::tcp_stream stream(ioc);
      stream.expires_after(timeout);
      stream.connect(endpoints);
      stream.socket().set_option(tcp::no_delay(true));
      plain.reset();
      secure.reset();
      if (use_tls) {
        secure = std::make_unique<TlsWs>(std::move(stream), *tls);
        beast::get_lowest_layer(*secure).expires_after(timeout);
        secure->next_layer().handshake(ssl::stream_base::client);
      } else {
        plain = std::make_unique<PlainWs>(std::move(stream));
      }
      const std::string origin = options.origin;
      std::string hello_text;
      With([&](auto& ws) {
        ws.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
          req.set(http::field::sec_websocket_protocol, "sweptccd.v1");
          if (!origin.empty()) req.set(http::field::origin, origin);
        }));
        ws.read_message_max(64 << 20);
        beast::get_lowest_layer(ws).expires_after(timeout);
        websocket::response_type res;
        beast::error_code ec;
        ws.handshake(res, host + ":" + std::to_string(port), DoorTarget(options.room), ec);
        if (ec == websocket::error::upgrade_declined && res.result() == http::status::conflict) {
          // The door holds another room (docs/WEBSOCKET.md section 1): resolve again.
          std::lock_guard<std::mutex> lock(mutex);
          ++stats.wrong_rooms;
          std::string why = res.body().substr(0, 160);
          while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
          throw std::runtime_error("door " + stats.door + " refused room '" + options.room +
                                   "' (409): " + why);
        }
        if (ec) throw beast::system_error(ec);
        beast::flat_buffer b;
        ws.read(b);
        hello_text = beast::buffers_to_string(b.data());
        beast::get_lowest_layer(ws).expires_never();
        ws.text(true);
      });
      const nlohmann::json hello = nlohmann::json::parse(hello_text);
      if (hello.value("type", "") != "hello") throw std::runtime_error("no hello");
      {
        std::lock_guard<std::mutex> lock(mutex);
        const int64_t hello_instance = hello.at("instance").get<int64_t>();
        if (hello_instance < max_instance) {
          // A server of an older run of this room (a stale allocation, a
          // host back from a partition): fenced, resolve again.
          ++stats.fenced_hellos;
          With([](auto& ws) {
            beast::error_code ec;
            beast::get_lowest_layer(ws).socket().close(ec);
          });
          throw std::runtime_error("door " + stats.door + " runs instance " +
                                   std::to_string(hello_instance) + ", older than instance " +
                                   std::to_string(max_instance) + " joined already: fenced");
        }
        if (const std::string problem = HelloRoomProblem(options.room, hello, stats.door);
            !problem.empty()) {
          ++stats.wrong_rooms;
          With([](auto& ws) {
            beast::error_code ec;
            beast::get_lowest_layer(ws).socket().close(ec);
          });
          throw std::runtime_error(problem);
        }
        challenge = hello.at("challenge").get<std::string>();
        instance = hello_instance;
        connected = true;
        ++connections;
        ++generation;
      }
      buffer.clear();
      out.clear();
      writing = false;
      if (options.skeleton) SendJoin();
      if (options.subscribe) {
        nlohmann::ordered_json s;
        s["type"] = "subscribe";
        s["proof"] = options.room_key ? ws::ComputeProof(*options.room_key,
                                                         ws::ProofKind::kSubscribe, challenge, "")
                                      : "";
        Queue(s.dump());
      }
      idle_ms = hello.contains("limits") ? hello["limits"].value("idle_timeout_ms", int64_t{15000})
                                         : int64_t{15000};
      SetPace(hello.contains("limits") ? hello["limits"] : nlohmann::json::object());
      // At least 3 status periods of this door (hello.limits.status_period_ms).
      heartbeat_s = options.heartbeat_timeout_s;
      if (hello.contains("limits") && hello["limits"].contains("status_period_ms") &&
          hello["limits"]["status_period_ms"].is_number_integer()) {
        const int64_t ms = hello["limits"]["status_period_ms"].get<int64_t>();
        if (ms > 0 && ms <= 3600000) heartbeat_s = std::max(heartbeat_s, 3 * ms / 1000.0);
      }
      Read(generation);
      KeepAlive(generation);
      Heartbeat(generation);
      return true;
    } catch (const std::exception& e) {
      plain.reset();
      secure.reset();
      std::lock_guard<std::mutex> lock(mutex);
      connected = false;
      ++failures;
      last_error = EscapeForDisplay(e.what(), 300);
      stats.last_error = last_error;
      cv.notify_all();
      return false;
    }
  }
  std::string last_error;
  int64_t idle_ms = 15000;
  net::steady_timer keepalive_timer{ioc};

  // A ping message every third of the door's idle timeout: a client with
  // nothing to send (between poses, a viewer) keeps its connection.
  void KeepAlive(uint64_t gen) {
    keepalive_timer.expires_after(std::chrono::milliseconds(std::max<int64_t>(idle_ms / 3, 10)));
    auto self = shared_from_this();
    keepalive_timer.async_wait([self, gen](beast::error_code ec) {
      if (ec || gen != self->generation) return;
      self->Queue("{\"type\":\"ping\",\"utime\":" + std::to_string(WallUtime()) + "}");
      self->KeepAlive(gen);
    });
  }

  // A joined client hears its instance's status every status_period_s; none
  // for heartbeat_timeout_s: the room is taken for dead (its host may be
  // gone without a FIN), the connection abandoned, the room resolved again.
  double heartbeat_s = 3;  // I/O thread: the timeout for this connection.
  void Heartbeat(uint64_t gen) {
    if (!(options.heartbeat_timeout_s > 0)) return;
    const auto timeout =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(heartbeat_s));
    heartbeat_timer.expires_after(
        std::max<Clock::duration>(timeout / 8, std::chrono::milliseconds(10)));
    auto self = shared_from_this();
    heartbeat_timer.async_wait([self, gen, timeout](beast::error_code ec) {
      if (ec || gen != self->generation) return;
      bool dead = false;
      {
        std::lock_guard<std::mutex> lock(self->mutex);
        dead = self->is_joined && Clock::now() - self->last_status > timeout;
        if (dead) ++self->stats.heartbeat_losses;
      }
      if (dead) {
        self->Abandon("no status from instance " + std::to_string(self->instance) + " for " +
                      std::to_string(self->heartbeat_s) + " s: room taken for dead");
        return;
      }
      self->Heartbeat(gen);
    });
  }

  // I/O thread: drops this connection (no close handshake: the peer may be
  // gone) and reconnects through the resolver.
  void Abandon(const std::string& why) {
    bool again = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      connected = false;
      is_joined = false;
      ++failures;
      ++generation;
      last_error = why;
      stats.last_error = why;
      again = options.reconnect && !left && !stopping;
      cv.notify_all();
    }
    With([](auto& ws) {
      beast::error_code ec;
      beast::get_lowest_layer(ws).socket().close(ec);
    });
    writing = false;
    out.clear();
    pose_out.clear();
    awaiting = -1;
    if (again) ScheduleReconnect();
  }

  // The pace of re-sent poses: under the door's message rate and the
  // service's pose rate (hello.limits), with a margin for pings.
  void SetPace(const nlohmann::json& limits) {
    const double message_rate = limits.value("message_rate_hz", 480.0);
    const double pose_limit = limits.value("max_pose_rate_hz", 240.0);
    const double burst =
        std::min(limits.value("message_burst", 64.0), limits.value("pose_burst", 16.0));
    pose_rate = std::max(1.0, 0.8 * std::min(message_rate, pose_limit));
    pose_burst = std::max(1.0, burst / 2);
    tokens = pose_burst;
    tokens_at = Clock::now();
    pose_out.clear();
    pump_armed = false;
    awaiting = -1;
  }

  void Pump() {
    const auto now = Clock::now();
    tokens = std::min(pose_burst,
                      tokens + pose_rate * std::chrono::duration<double>(now - tokens_at).count());
    tokens_at = now;
    while (!pose_out.empty() && awaiting < 0 && tokens >= 1) {
      OutPose p = std::move(pose_out.front());
      pose_out.pop_front();
      Queue(std::move(p.text));
      tokens -= 1;
      if (!p.anchor) AwaitPair(p.seq);
    }
    if (pose_out.empty() || awaiting >= 0 || pump_armed) return;
    pump_armed = true;
    pump_timer.expires_after(std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>((1 - tokens) / pose_rate)));
    auto self = shared_from_this();
    const uint64_t gen = generation;
    pump_timer.async_wait([self, gen](beast::error_code ec) {
      if (ec || gen != self->generation) return;
      self->pump_armed = false;
      self->Pump();
    });
  }

  void AwaitPair(int64_t seq) {
    awaiting = seq;
    lockstep_timer.expires_after(kLockstepWait);
    auto self = shared_from_this();
    const uint64_t gen = generation;
    lockstep_timer.async_wait([self, gen, seq](beast::error_code ec) {
      if (ec || gen != self->generation || self->awaiting != seq) return;
      self->awaiting = -1;  // No answer (shed, suppressed rejection): go on.
      self->Pump();
    });
  }

  // An answer or a rejection of our pose `seq` arrived (I/O thread).
  void PairDone(int64_t seq) {
    if (awaiting < 0 || seq < awaiting) return;
    awaiting = -1;
    lockstep_timer.cancel();
    Pump();
  }

  // A live pose: straight out, unless re-sent ones are still going out.
  void SendLive(int64_t seq, std::string text) {
    if (pose_out.empty() && awaiting < 0) {
      Queue(std::move(text));
      return;
    }
    pose_out.push_back({seq, false, std::move(text)});
    Pump();
  }

  void SendJoin() {
    join_request_t r{};
    r.utime = WallUtime();
    r.client_id = options.client_id;
    r.nonce = nonce;
    r.motion = options.motion == MotionModel::kIndependent ? join_request_t::MOTION_INDEPENDENT
                                                           : join_request_t::MOTION_ARTICULATED;
    r.eps_s = options.eps_s;
    r.delta_m = options.delta_m;
    FillJoinSkeleton(*options.skeleton, &r);
    r.ignore = options.ignore;
    r.num_ignore = static_cast<int32_t>(r.ignore.size());
    for (const EntityIgnore& e : options.ignore_entities) {
      r.ignore_entity_link.push_back(e.link);
      r.ignore_entity.push_back(e.entity);
      r.ignore_entity_other_link.push_back(e.other_link);
    }
    r.num_ignore_entities = static_cast<int32_t>(r.ignore_entity.size());
    const std::string proof =
        options.room_key
            ? ws::ComputeProof(*options.room_key, ws::ProofKind::kJoin, challenge, r.client_id)
            : "";
    Queue(ws::ToJson(r, proof).dump());
  }

  // I/O thread.
  void Queue(std::string text) {
    out.push_back(std::move(text));
    Write();
  }

  void Write() {
    if (writing || out.empty() || (!plain && !secure)) return;
    writing = true;
    auto self = shared_from_this();
    auto text = std::make_shared<std::string>(std::move(out.front()));
    out.pop_front();
    const uint64_t gen = generation;
    With([&](auto& ws) {
      ws.async_write(net::buffer(*text), [self, text, gen](beast::error_code ec, size_t) {
        if (gen != self->generation) return;
        self->writing = false;
        if (ec) return;  // The read side notices and reconnects.
        self->Write();
      });
    });
  }

  void Read(uint64_t gen) {
    auto self = shared_from_this();
    With([&](auto& ws) {
      ws.async_read(buffer, [self, gen](beast::error_code ec, size_t) {
        if (gen != self->generation) return;
        if (ec) {
          self->Dropped();
          return;
        }
        const std::string text = beast::buffers_to_string(self->buffer.data());
        self->buffer.consume(self->buffer.size());
        self->OnMessage(text);
        self->Read(gen);
      });
    });
  }

  void Dropped() {
    bool again = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      connected = false;
      is_joined = false;
      ++failures;
      ++generation;
      again = options.reconnect && !left && !stopping;
      cv.notify_all();
    }
    writing = false;
    if (!again) return;
    ScheduleReconnect();
  }

  void ScheduleReconnect() {
    std::uniform_int_distribution<int> jitter(0, static_cast<int>(backoff.count() / 4));
    static thread_local std::mt19937 rng{std::random_device{}()};
    backoff_timer.expires_after(backoff + std::chrono::milliseconds(jitter(rng)));
    backoff = std::min<std::chrono::milliseconds>(
        backoff * 2, std::chrono::milliseconds(static_cast<int64_t>(options.max_backoff_s * 1000)));
    auto self = shared_from_this();
    backoff_timer.async_wait([self](beast::error_code ec) {
      if (ec) return;
      {
        std::lock_guard<std::mutex> lock(self->mutex);
        if (self->left || self->stopping) return;
      }
      if (self->Connect()) {
        self->backoff = std::chrono::milliseconds(250);
      } else {
        self->ScheduleReconnect();
      }
    });
  }

  // Whether an event of `type` with instance `v.instance` is stale (another
  // daemon run than this connection's): counted and dropped.
  bool Fenced(const nlohmann::json& v) {
    const auto it = v.find("instance");
    if (it == v.end() || !it->is_number_integer()) return false;
    std::lock_guard<std::mutex> lock(mutex);
    if (!IsStaleEpoch(it->get<int64_t>(), instance)) return false;
    ++stats.fenced_events;
    return true;
  }

  void OnJoinReply(const join_reply_t& r) {
    std::vector<tracker_pose_t> again;
    {
      std::lock_guard<std::mutex> lock(mutex);
      JoinResult result;
      result.reason = r.reason;
      result.message = EscapeForDisplay(r.message, 400);
      result.session = r.session;
      result.instance = r.instance;
      if (result.ok()) {
        is_joined = true;
        ever_joined = true;
        session = r.session;
        instance = r.instance;
        max_instance = std::max(max_instance, r.instance);
        last_status = Clock::now();
        // The poses whose pair is not answered yet, again under the new
        // session (same seq and utime): a pair answered by nobody is
        // answered now, one answered already is dropped when it comes again.
        again = ledger.ForResend(r.session);
        stats.resent_poses += static_cast<int64_t>(again.size());
      }
      last_reply = result;
      ++replies;
      cv.notify_all();
    }
    for (tracker_pose_t& p : again) {
      p.num_links = static_cast<int32_t>(p.position.size());
      pose_out.push_back({p.seq, pose_out.empty(), ws::ToJson(p).dump()});
    }
    if (!again.empty()) Pump();
  }

  // Whether an answer for our own pair ending at seq1 is new (deliver it).
  bool FirstAnswer(const std::string& client_id, int64_t seq1) {
    if (client_id != options.client_id) return true;  // A viewer's copy of another's.
    std::lock_guard<std::mutex> lock(mutex);
    if (ledger.Answered(seq1)) return true;
    ++stats.repeated_answers;
    return false;
  }

  // A pair's shared entries come in one or more messages (one entry per
  // other entity): entries already delivered are removed; false when none is
  // left.
  bool FirstSharedEntries(shared_contact_t* e) {
    if (e->client_id != options.client_id) return true;
    std::lock_guard<std::mutex> lock(mutex);
    std::vector<shared_entry_t> fresh;
    for (shared_entry_t& entry : e->entries) {
      if (shared_seen.insert({e->seq1, entry.entity}).second) fresh.push_back(std::move(entry));
    }
    while (shared_seen.size() > 16384) shared_seen.erase(shared_seen.begin());
    const bool any = !fresh.empty();
    if (fresh.size() < e->entries.size()) ++stats.repeated_answers;
    e->entries = std::move(fresh);
    e->num_entries = static_cast<int32_t>(e->entries.size());
    return any;
  }

  // False: the rejection made this client re-join (unknown_client).
  bool OnOwnRejection(const rejection_t& e) {
    if (e.client_id != options.client_id) return true;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (e.reason != "unknown_client") {
        ledger.Refused(e.seq);
        return true;
      }
      if (!is_joined || left) return true;
      ++stats.unknown_client_rejoins;
    }
    // The daemon dropped the session (silence): join again on a new
    // connection; the refused pose is still pending and goes out again.
    Abandon("rejection unknown_client: the daemon dropped the session; joining again");
    return false;
  }

  void OnMessage(const std::string& text) {
    WireLimits limits;
    limits.max_links = 1 << 16;
    nlohmann::json v = nlohmann::json::parse(text, nullptr, false);
    if (v.is_discarded() || !v.is_object()) return;
    const std::string type = v.value("type", "");
    try {
      if (type != "join_reply" && Fenced(v)) return;
      if (type == "join_reply") {
        join_reply_t r{};
        ws::FromJson(v, limits, &r);
        OnJoinReply(r);
        if (owner->on_join_reply_) owner->on_join_reply_(r);
      } else if (type == "contact_event") {
        contact_event_t e{};
        ws::FromJson(v, limits, &e);
        if (e.client_id == options.client_id) PairDone(e.seq1);
        if (!FirstAnswer(e.client_id, e.seq1)) return;
        if (owner->on_contact_) owner->on_contact_(e);
      } else if (type == "shared_contact") {
        shared_contact_t e{};
        ws::FromJson(v, limits, &e);
        if (!FirstSharedEntries(&e)) return;
        if (owner->on_shared_) owner->on_shared_(e);
      } else if (type == "rejection") {
        rejection_t e{};
        ws::FromJson(v, limits, &e);
        if (owner->on_rejection_) owner->on_rejection_(e);
        if (!OnOwnRejection(e)) return;
        if (e.client_id == options.client_id) PairDone(e.seq);
      } else if (type == "status") {
        status_t e{};
        ws::FromJson(v, limits, &e);
        last_status = Clock::now();
        if (owner->on_status_) owner->on_status_(e);
      } else if (type == "error") {
        if (owner->on_error_) {
          owner->on_error_(v.value("code", std::string()), v.value("message", std::string()));
        }
      }
    } catch (const std::exception&) {
      // A message the client cannot read is skipped (a newer server's field).
    }
    if (owner->on_text_) owner->on_text_(text);
  }
};

WsLiveClient::WsLiveClient(Options options)
    : impl_(std::make_shared<Impl>(this, std::move(options))) {
  if (impl_->options.skeleton && !IsValidClientId(impl_->options.client_id)) {
    throw InputError("client id '" + EscapeForDisplay(impl_->options.client_id) +
                     "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
  }
  impl_->thread = std::thread([impl = impl_.get()] { impl->ioc.run(); });
}

WsLiveClient::~WsLiveClient() {
  Leave();
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->stopping = true;
  }
  net::post(impl_->ioc, [impl = impl_.get()] {
    impl->backoff_timer.cancel();
    impl->keepalive_timer.cancel();
    impl->heartbeat_timer.cancel();
    impl->pump_timer.cancel();
    impl->lockstep_timer.cancel();
    beast::error_code ec;
    if (impl->plain) beast::get_lowest_layer(*impl->plain).socket().close(ec);
    if (impl->secure) beast::get_lowest_layer(*impl->secure).socket().close(ec);
    impl->work.reset();
  });
  impl_->thread.join();
}

JoinResult WsLiveClient::Join() {
  Impl* impl = impl_.get();
  int64_t replies_before, failures_before;
  {
    std::lock_guard<std::mutex> lock(impl->mutex);
    replies_before = impl->replies;
    failures_before = impl->failures;
  }
  // Without reconnect a failed or dropped connection ends the wait.
  const auto failed = [&] { return !impl->options.reconnect && impl->failures > failures_before; };
  net::post(impl->ioc, [impl] {
    if (!impl->Connect() && impl->options.reconnect) impl->ScheduleReconnect();
  });
  std::unique_lock<std::mutex> lock(impl->mutex);
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(impl->options.join_timeout_s));
  if (!impl->options.skeleton) {
    impl->cv.wait_until(lock, deadline, [&] { return impl->connected || failed(); });
    JoinResult r;
    r.reason = impl->connected ? 0 : -1;
    r.instance = impl->instance;
    r.message = impl->connected ? "" : "no connection: " + impl->last_error;
    return r;
  }
  impl->cv.wait_until(lock, deadline, [&] { return impl->replies > replies_before || failed(); });
  if (impl->replies > replies_before && impl->last_reply) return *impl->last_reply;
  JoinResult r;
  r.message =
      (failed() ? std::string("no connection")
                : "no join reply within " + std::to_string(impl->options.join_timeout_s) + " s") +
      (impl->last_error.empty() ? "" : " (" + impl->last_error + ")");
  return r;
}

bool WsLiveClient::PublishPose(tracker_pose_t pose) {
  Impl* impl = impl_.get();
  int64_t session = 0;
  pose.num_links = static_cast<int32_t>(pose.position.size());
  {
    std::lock_guard<std::mutex> lock(impl->mutex);
    if (impl->left || (!impl->is_joined && !impl->ever_joined)) return false;
    pose.client_id = impl->options.client_id;
    impl->ledger.Sent(pose);  // Counted in failover().forgotten_poses when over the bound.
    if (!impl->is_joined) return true;  // Re-joining: it goes out after the join.
    session = impl->session;
  }
  pose.session = session;
  auto text = std::make_shared<std::string>(ws::ToJson(pose).dump());
  net::post(impl->ioc, [impl, text, session, seq = pose.seq] {
    {
      std::lock_guard<std::mutex> lock(impl->mutex);
      if (!impl->is_joined || impl->session != session) return;  // Re-sent after the re-join.
    }
    impl->SendLive(seq, std::move(*text));
  });
  return true;
}

std::string WsLiveClient::PublishJointFrame(const JointSkeleton& joints, const JointFrame& frame,
                                            int64_t seq) {
  const std::optional<Skeleton>& skeleton = impl_->options.skeleton;  // Immutable after start.
  tracker_pose_t m;
  if (std::string problem =
          TrackerPoseOfJointFrame(joints, frame, skeleton ? skeleton->num_links() : -1, seq, &m);
      !problem.empty()) {
    return problem;
  }
  if (!PublishPose(std::move(m))) return "not joined (no session), or left";
  return "";
}

bool WsLiveClient::Send(const std::string& text) {
  Impl* impl = impl_.get();
  {
    std::lock_guard<std::mutex> lock(impl->mutex);
    if (!impl->connected) return false;
  }
  net::post(impl->ioc, [impl, text] { impl->Queue(text); });
  return true;
}

void WsLiveClient::Leave() {
  Impl* impl = impl_.get();
  leave_t leave{};
  {
    std::lock_guard<std::mutex> lock(impl->mutex);
    if (impl->left) return;
    impl->left = true;
    if (!impl->is_joined) return;
    impl->is_joined = false;
    leave.utime = WallUtime();
    leave.client_id = impl->options.client_id;
    leave.session = impl->session;
  }
  auto text = std::make_shared<std::string>(ws::ToJson(leave).dump());
  auto sent = std::make_shared<std::promise<void>>();
  auto done = sent->get_future();
  net::post(impl->ioc, [impl, text, sent] {
    impl->Queue(std::move(*text));
    sent->set_value();
  });
  done.wait_for(std::chrono::seconds(2));
  // Give the leave a moment to go out before the socket closes.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
}

bool WsLiveClient::joined() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->is_joined;
}

int64_t WsLiveClient::session() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->session;
}

int64_t WsLiveClient::instance() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->instance;
}

int64_t WsLiveClient::reconnects() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return std::max<int64_t>(0, impl_->connections - 1);
}

std::string WsLiveClient::challenge() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->challenge;
}

const std::string& WsLiveClient::client_id() const { return impl_->options.client_id; }

WsLiveClient::FailoverStats WsLiveClient::failover() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  FailoverStats s = impl_->stats;
  s.forgotten_poses = impl_->ledger.forgotten();
  return s;
}

}  // namespace sweptccd
