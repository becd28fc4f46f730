// ws_attack_tool: attacks on the daemon's WebSocket door
// (tests/service/e2e_websocket_attacks.sh), each bounded in count and time,
// each from its own loopback source address (127.0.0.2...) so the caps per
// address meet the attacker, not the good client on 127.0.0.1.
//
//   ws_attack_tool PORT ROOM_KEY_FILE PER_ADDRESS HANDSHAKE_MS MAX_MESSAGE_BYTES
//
// flood: 4 x PER_ADDRESS connections from one address: all beyond the cap
//   closed at once. slowloris: handshakes sent a byte at a time: closed by
//   the handshake timeout. oversized: one message over the cap, and one
//   fragmented over it: closed 1009. fragmented: a small message in two
//   fragments: answered. malformed: garbage, a binary frame, an unknown
//   type, a bad field: each its error, the connection stays. wrong_key: a
//   join with a proof under another key: bad_proof, closed 1008. rate: a
//   burst far over the message rate: rate_limited, the connection stays.
//   never_reads: a client that never reads while asking for answers (error
//   frames): closed by the door (slow_reader) within seconds.
// Prints one line per attack ("ok NAME: ..." or "FAIL NAME: ..."); exit 0
// when all hold.
//
//   ws_attack_tool replace PORT ROOM_KEY_FILE
//   ws_attack_tool reconnect PORT ROOM_KEY_FILE SKELETON
// Not attacks: a reconnection taking its id over (`replaced`), and the C++
// client across a daemon restart (docs/WEBSOCKET.md section 9).

#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <functional>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "msgs/signing.h"
#include "service/ws/proof.h"
#include "sweptccd_client/ws_client.h"

namespace {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

int g_port = 0;
std::atomic<int> g_failures{0};

void Report(bool ok, const char* name, const std::string& what) {
  std::printf("%s %s: %s\n", ok ? "ok" : "FAIL", name, what.c_str());
  std::fflush(stdout);
  if (!ok) ++g_failures;
}

tcp::socket Connect(net::io_context& ioc, const char* source, int rcvbuf = 0) {
  tcp::socket s(ioc);
  s.open(tcp::v4());
  if (rcvbuf > 0) s.set_option(net::socket_base::receive_buffer_size(rcvbuf));
  s.bind(tcp::endpoint(net::ip::make_address(source), 0));
  s.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<uint16_t>(g_port)));
  return s;
}

// Whether the peer closed `fd` (EOF or reset) within `ms`.
bool ClosedWithin(int fd, int ms) {
  const auto deadline = Clock::now() + std::chrono::milliseconds(ms);
  char buf[4096];
  while (Clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    const int left = static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count());
    if (poll(&p, 1, std::max(left, 1)) <= 0) continue;
    const ssize_t n = recv(fd, buf, sizeof(buf), MSG_DONTWAIT);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return true;
  }
  return false;
}

using Ws = websocket::stream<tcp::socket>;

std::unique_ptr<Ws> Open(net::io_context& ioc, const char* source, std::string* challenge,
                         int rcvbuf = 0) {
  auto ws = std::make_unique<Ws>(Connect(ioc, source, rcvbuf));
  ws->set_option(websocket::stream_base::decorator([](websocket::request_type& req) {
    req.set(beast::http::field::sec_websocket_protocol, "sweptccd.v1");
  }));
  ws->read_message_max(1 << 20);
  ws->handshake("127.0.0.1", "/ws");
  beast::flat_buffer b;
  ws->read(b);
  const auto hello = nlohmann::json::parse(beast::buffers_to_string(b.data()));
  if (challenge) *challenge = hello.at("challenge").get<std::string>();
  ws->text(true);
  return ws;
}

// Reads messages until one of `type` (and `code` for errors) arrives, the
// connection closes, or `ms` pass. Returns the message, or "" (then
// *close_code holds the close code when closed).
std::string ReadUntil(Ws& ws, const std::string& type, const std::string& code, int ms,
                      int* close_code = nullptr) {
  // One socket read can bring Beast several frames, which it then holds: the
  // socket's readiness says nothing about the next message (polling it first
  // missed a rate_limited error already buffered). Each read runs
  // asynchronously under the deadline instead.
  auto& ioc = static_cast<net::io_context&>(ws.get_executor().context());
  const auto deadline = Clock::now() + std::chrono::milliseconds(ms);
  while (Clock::now() < deadline) {
    beast::flat_buffer b;
    beast::error_code ec;
    bool done = false;
    ws.async_read(b, [&](beast::error_code e, size_t) {
      ec = e;
      done = true;
    });
    ioc.restart();
    ioc.run_until(deadline);
    if (!done) {  // Out of time: abandon the read (the stream is not used for reading again).
      beast::error_code ignored;
      ws.next_layer().cancel(ignored);
      ioc.restart();
      ioc.run();
      return "";
    }
    if (ec) {
      if (close_code) *close_code = ws.reason().code;
      return "";
    }
    const std::string text = beast::buffers_to_string(b.data());
    const auto j = nlohmann::json::parse(text, nullptr, false);
    if (j.is_object() && j.value("type", "") == type &&
        (code.empty() || j.value("code", "") == code)) {
      return text;
    }
  }
  return "";
}

void Flood(int per_address) {
  net::io_context ioc;
  const int n = 4 * per_address;
  std::vector<tcp::socket> sockets;
  for (int i = 0; i < n; ++i) sockets.push_back(Connect(ioc, "127.0.0.2"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  int closed = 0;
  for (auto& s : sockets) closed += ClosedWithin(s.native_handle(), 1);
  Report(closed >= n - per_address && n - closed <= per_address, "flood",
         std::to_string(n) + " connections from one address, " + std::to_string(closed) +
             " closed at once (cap " + std::to_string(per_address) + ")");
}

void Slowloris(int handshake_ms) {
  net::io_context ioc;
  const std::string request = "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n";
  std::vector<tcp::socket> sockets;
  for (int i = 0; i < 4; ++i) sockets.push_back(Connect(ioc, "127.0.0.3"));
  const auto t0 = Clock::now();
  std::vector<bool> closed(sockets.size(), false);
  size_t sent = 0;
  while (Clock::now() - t0 < std::chrono::milliseconds(handshake_ms + 2000)) {
    bool all = true;
    for (size_t i = 0; i < sockets.size(); ++i) {
      if (closed[i]) continue;
      beast::error_code ec;
      if (sent < request.size()) net::write(sockets[i], net::buffer(&request[sent], 1), ec);
      if (ec || ClosedWithin(sockets[i].native_handle(), 1)) {
        closed[i] = true;
      } else {
        all = false;
      }
    }
    if (all) break;
    ++sent;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  int n = 0;
  for (bool c : closed) n += c;
  Report(n == static_cast<int>(sockets.size()) && s < handshake_ms / 1000.0 + 1.5, "slowloris",
         std::to_string(n) + " of " + std::to_string(sockets.size()) +
             " byte-a-time handshakes closed after " + std::to_string(s) + " s (timeout " +
             std::to_string(handshake_ms) + " ms)");
}

void Oversized(size_t max_bytes) {
  net::io_context ioc;
  {
    auto ws = Open(ioc, "127.0.0.4", nullptr);
    beast::error_code ec;
    ws->write(net::buffer(std::string(max_bytes + 1000, ' ')), ec);
    int code = 0;
    ReadUntil(*ws, "none", "", 3000, &code);
    Report(code == 1009, "oversized",
           "one message of " + std::to_string(max_bytes + 1000) + " bytes: closed with " +
               std::to_string(code));
  }
  {
    auto ws = Open(ioc, "127.0.0.4", nullptr);
    beast::error_code ec;
    const std::string chunk(max_bytes / 4, ' ');
    for (int i = 0; i < 6 && !ec; ++i) ws->write_some(false, net::buffer(chunk), ec);
    // -1: still open. The door closes with 1009 while fragments may still be
    // on their way: the close frame can be lost to a reset (code 0); the
    // script checks the door's log line for both oversized messages.
    int code = -1;
    if (!ec) ReadUntil(*ws, "none", "", 3000, &code);
    if (ec) code = 0;
    Report(code == 1009 || code == 0, "oversized_fragmented",
           "6 fragments of " + std::to_string(chunk.size()) + " bytes: closed" +
               (code == 1009 ? " with 1009"
                : code == 0  ? " (reset)"
                             : ": NOT closed"));
  }
  {
    auto ws = Open(ioc, "127.0.0.4", nullptr);
    ws->write_some(false, net::buffer(std::string(R"({"type":)")));
    ws->write_some(true, net::buffer(std::string(R"("ping","utime":7})")));
    const std::string pong = ReadUntil(*ws, "pong", "", 2000);
    Report(pong.find("\"utime\":7") != std::string::npos, "fragmented",
           "a ping in two fragments: " + (pong.empty() ? std::string("no answer") : pong));
  }
}

void Malformed() {
  net::io_context ioc;
  auto ws = Open(ioc, "127.0.0.5", nullptr);
  const std::pair<std::string, std::string> cases[] = {
      {"{nope", "bad_json"},
      {"[1,2,3]", "bad_json"},
      {std::string(100, '[') + std::string(100, ']'), "bad_json"},
      {R"({"type":"launch_missiles"})", "unknown_type"},
      {R"({"type":"tracker_pose","utime":"x"})", "bad_message"},
      {R"({"type":"tracker_pose","utime":1,"client_id":"a","session":1,"seq":1,"position":[],"orientation":[]})",
       "not_joined"},
  };
  int ok = 0;
  for (const auto& [text, code] : cases) {
    ws->write(net::buffer(text));
    ok += !ReadUntil(*ws, "error", code, 2000).empty();
  }
  ws->binary(true);
  ws->write(net::buffer(std::string("\x01\x02", 2)));
  ws->text(true);
  ok += !ReadUntil(*ws, "error", "binary_frame", 2000).empty();
  ws->write(net::buffer(std::string(R"({"type":"ping","utime":9})")));
  const bool alive = !ReadUntil(*ws, "pong", "", 2000).empty();
  Report(ok == 7 && alive, "malformed",
         std::to_string(ok) + " of 7 bad messages answered with their error code; " +
             (alive ? "still open" : "closed"));
}

void WrongKey() {
  net::io_context ioc;
  std::string challenge;
  auto ws = Open(ioc, "127.0.0.6", &challenge);
  std::array<uint8_t, sweptccd::kKeyBytes> other{};
  other.fill(0x5a);
  const std::string proof = sweptccd::ws::ComputeProof(
      sweptccd::MacKey(other), sweptccd::ws::ProofKind::kJoin, challenge, "mallory");
  ws->write(net::buffer(
      R"({"type":"join_request","utime":1,"client_id":"mallory","nonce":1,"motion":0,"eps_s":0,)"
      R"("delta_m":0,"link_name":["a"],"parent":[-1],"a":[[0,0,0]],"b":[[0,0.1,0]],)"
      R"("radius":[0.05],"proof":")" +
      proof + "\"}"));
  const bool error = !ReadUntil(*ws, "error", "bad_proof", 2000).empty();
  int code = 0;
  ReadUntil(*ws, "none", "", 3000, &code);
  Report(error && code == 1008, "wrong_key",
         std::string("join under another key: ") + (error ? "bad_proof" : "no bad_proof") +
             ", closed with " + std::to_string(code));
}

void Rate() {
  net::io_context ioc;
  auto ws = Open(ioc, "127.0.0.7", nullptr);
  const int n = 3000;
  for (int i = 0; i < n; ++i) ws->write(net::buffer(std::string(R"({"type":"ping"})")));
  const bool limited = !ReadUntil(*ws, "error", "rate_limited", 3000).empty();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ws->write(net::buffer(std::string(R"({"type":"ping","utime":5})")));
  const bool alive = !ReadUntil(*ws, "pong", "", 3000).empty();
  Report(limited && alive, "rate",
         std::to_string(n) + " messages at once: " + (limited ? "rate_limited" : "not limited") +
             ", " + (alive ? "still open" : "closed"));
}

void NeverReads() {
  net::io_context ioc;
  auto ws = Open(ioc, "127.0.0.8", nullptr, 2048);
  // Each bad message asks for an error frame of its own: answers the
  // reader never takes.
  const std::string text = R"({"type":")" + std::string(60, 'x') + R"("})";
  const auto t0 = Clock::now();
  bool closed = false;
  while (Clock::now() - t0 < std::chrono::seconds(8)) {
    beast::error_code ec;
    for (int i = 0; i < 20 && !ec; ++i) ws->write(net::buffer(text), ec);
    if (ec) {
      closed = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  Report(closed, "never_reads",
         std::string("a client that never reads: ") +
             (closed ? "closed by the door after " + std::to_string(s) + " s" : "still open"));
}

std::string JoinText(const std::string& id, int64_t nonce, const std::string& challenge,
                     const sweptccd::MacKey& key) {
  const std::string proof =
      sweptccd::ws::ComputeProof(key, sweptccd::ws::ProofKind::kJoin, challenge, id);
  const auto now = std::chrono::duration_cast<std::chrono::microseconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count();
  return R"({"type":"join_request","utime":)" + std::to_string(now) + R"(,"client_id":")" + id +
         R"(","nonce":)" + std::to_string(nonce) +
         R"(,"motion":0,"eps_s":0,"delta_m":0,"link_name":["a"],"parent":[-1],)"
         R"("a":[[0,0,0]],"b":[[0,0.1,0]],"radius":[0.05],"proof":")" +
         proof + "\"}";
}

// A second connection of the same client instance (same id and nonce, a
// valid proof) takes the id over: the first gets `replaced` and is closed,
// the second a greater session. Another nonce meanwhile: id_in_use.
int Replace(const sweptccd::MacKey& key) {
  net::io_context ioc;
  std::string c1, c2, c3;
  auto first = Open(ioc, "127.0.0.9", &c1);
  first->write(net::buffer(JoinText("rita", 42, c1, key)));
  const std::string r1 = ReadUntil(*first, "join_reply", "", 5000);
  const auto j1 = nlohmann::json::parse(r1.empty() ? "{}" : r1);
  auto other = Open(ioc, "127.0.0.9", &c3);
  other->write(net::buffer(JoinText("rita", 43, c3, key)));
  const std::string r3 = ReadUntil(*other, "join_reply", "", 5000);
  auto second = Open(ioc, "127.0.0.9", &c2);
  second->write(net::buffer(JoinText("rita", 42, c2, key)));
  const std::string r2 = ReadUntil(*second, "join_reply", "", 5000);
  const auto j2 = nlohmann::json::parse(r2.empty() ? "{}" : r2);
  const bool replaced = !ReadUntil(*first, "error", "replaced", 3000).empty();
  const bool ok = j1.value("reason", -1) == 0 && j2.value("reason", -1) == 0 &&
                  j2.value("session", int64_t{0}) > j1.value("session", int64_t{0}) && replaced &&
                  r3.find("\"reason_name\":\"id_in_use\"") != std::string::npos;
  Report(ok, "replace",
         "the same id and nonce again: " +
             std::string(replaced ? "old one replaced" : "old one kept") + ", sessions " +
             std::to_string(j1.value("session", int64_t{0})) + " -> " +
             std::to_string(j2.value("session", int64_t{0})) +
             "; another nonce: " + (r3.find("id_in_use") != std::string::npos ? "id_in_use" : r3));
  return g_failures.load() == 0 ? 0 : 1;
}

// WsLiveClient across a daemon restart: joined, poses answered; the script
// restarts the daemon; the client reconnects with backoff, joins again (a
// new instance) and its poses are answered again. Prints progress lines the
// script waits for.
int Reconnect(const sweptccd::MacKey& key, const std::string& skeleton_path) {
  using namespace sweptccd;
  WsLiveClient::Options o;
  o.port = static_cast<uint16_t>(g_port);
  o.client_id = "ria";
  o.room_key = key;
  o.skeleton = LoadSkeletonFile(skeleton_path);
  WsLiveClient client(o);
  std::mutex mutex;
  std::set<int64_t> instances;
  int64_t events = 0, events_after = 0;
  client.OnJoinReply([&](const join_reply_t& r) {
    std::lock_guard<std::mutex> lock(mutex);
    if (r.reason == 0) instances.insert(r.instance);
    std::printf("reconnect: joined instance %lld session %lld\n",
                static_cast<long long>(r.instance), static_cast<long long>(r.session));
    std::fflush(stdout);
  });
  client.OnContact([&](const contact_event_t&) {
    std::lock_guard<std::mutex> lock(mutex);
    ++events;
    if (instances.size() >= 2) ++events_after;
  });
  if (!client.Join().ok()) {
    Report(false, "reconnect", "first join failed");
    return 1;
  }
  const auto t0 = Clock::now();
  int64_t seq = 0;
  while (Clock::now() - t0 < std::chrono::seconds(20)) {
    tracker_pose_t p{};
    p.utime = 1000000 + seq * 20000;
    p.seq = seq++;
    for (int l = 0; l < o.skeleton->num_links(); ++l) {
      p.position.push_back({0, 1, 0.3 * l});
      p.orientation.push_back({1, 0, 0, 0});
    }
    client.PublishPose(p);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::lock_guard<std::mutex> lock(mutex);
    if (instances.size() >= 2 && events_after >= 10) break;
  }
  std::lock_guard<std::mutex> lock(mutex);
  Report(instances.size() >= 2 && events_after >= 10 && client.reconnects() >= 1, "reconnect",
         std::to_string(instances.size()) + " daemon instances joined, " +
             std::to_string(client.reconnects()) + " reconnects, " + std::to_string(events_after) +
             " events after the restart");
  return g_failures.load() == 0 ? 0 : 1;
}

// WsLiveClient after the daemon dropped its session for silence (its
// silence_timeout_ms, 300 ms in the script; paused longer than that after
// the fifth pose): its next pose is rejected
// unknown_client, the client re-joins at once on a new connection and sends
// the pending poses again; every pair is answered exactly once. A pair is
// (seq0, seq1): when the daemon falls behind, latest-wins merges pending
// pairs (docs/SERVICE.md, "Scheduling": (2, 3) and (3, 4) answered as one
// (2, 4)), so "every pair once" is checked as the answers' chain: sorted by
// seq1, each starts where the previous ended, from pose 0 to the last pose
// (no motion lost, none answered twice), and each seq1 is delivered once.
int Silence(const sweptccd::MacKey& key, const std::string& skeleton_path) {
  using namespace sweptccd;
  WsLiveClient::Options o;
  o.port = static_cast<uint16_t>(g_port);
  o.client_id = "quiet";
  o.room_key = key;
  o.skeleton = LoadSkeletonFile(skeleton_path);
  WsLiveClient client(o);
  std::mutex mutex;
  std::map<int64_t, std::vector<int64_t>> answers;  // seq1 -> seq0 of each delivery
  std::set<int64_t> sessions;
  int64_t timeout_ms = 0;  // The daemon's silence_timeout_ms, from its join reply.
  client.OnJoinReply([&](const join_reply_t& r) {
    std::lock_guard<std::mutex> lock(mutex);
    if (r.reason == 0) sessions.insert(r.session);
    if (r.reason == 0) timeout_ms = r.silence_timeout_ms;
  });
  client.OnContact([&](const contact_event_t& e) {
    std::lock_guard<std::mutex> lock(mutex);
    answers[e.seq1].push_back(e.seq0);
  });
  client.OnRejection([&](const rejection_t& r) {
    std::printf("silence: rejection of seq %lld: %s\n", static_cast<long long>(r.seq),
                r.reason.c_str());
  });
  if (!client.Join().ok()) {
    Report(false, "silence", "first join failed");
    return 1;
  }
  // The pause: the daemon drops a silent client between the timeout and 9/8
  // of it after the last pose it heard (docs/SERVICE.md), if it runs then;
  // 1.5 s more for a daemon stalled on a loaded machine (stalls of several
  // hundred ms seen on 2 cores).
  // (The reply's callback runs just after Join() returns: wait for it.)
  int64_t pause_ms = 0;
  for (int i = 0; i < 200 && pause_ms == 0; ++i) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (timeout_ms > 0) pause_ms = timeout_ms * 9 / 8 + 1500;
    }
    if (pause_ms == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (timeout_ms < 1 || timeout_ms > 2000) {
    Report(false, "silence",
           "the daemon's silence_timeout_ms is " + std::to_string(timeout_ms) +
               "; this check needs one in [1, 2000] ms (--silence-timeout-ms)");
    return 1;
  }
  const int64_t kPoses = 30;
  for (int64_t seq = 0; seq < kPoses; ++seq) {
    if (seq == 5) std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms));
    tracker_pose_t p{};
    p.utime = 1000000 + seq * 20000;
    p.seq = seq;
    for (int l = 0; l < o.skeleton->num_links(); ++l) {
      p.position.push_back({0, 1, 0.3 * l});
      p.orientation.push_back({1, 0, 0, 0});
    }
    if (!client.PublishPose(p))
      Report(false, "silence", "pose " + std::to_string(seq) + " refused");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Until the last pose's pair is in (bounded: 3 s), then anything more (a
  // repeat would show now).
  for (int i = 0; i < 300; ++i) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (answers.count(kPoses - 1)) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::lock_guard<std::mutex> lock(mutex);
  // The chain from pose 0: its first break (a gap, an overlap or a repeat).
  int64_t end = 0, merged = 0;
  std::string broken;
  for (const auto& [seq1, seq0s] : answers) {
    if (seq0s.size() != 1) {
      broken += " seq1 " + std::to_string(seq1) + " delivered " + std::to_string(seq0s.size()) +
                " times;";
    }
    if (seq0s[0] != end) {
      broken += " (" + std::to_string(seq0s[0]) + ", " + std::to_string(seq1) +
                ") after the chain reached " + std::to_string(end) + ";";
    }
    merged += seq1 - seq0s[0] > 1;
    end = std::max(end, seq1);
  }
  if (end != kPoses - 1) broken += " the chain ends at " + std::to_string(end) + ";";
  if (!broken.empty()) std::printf("silence: pairs:%s\n", broken.c_str());
  const bool once = broken.empty();
  const auto f = client.failover();
  Report(once && f.unknown_client_rejoins >= 1 && sessions.size() >= 2, "silence",
         std::to_string(answers.size()) + " pairs answered for poses 0-" +
             std::to_string(kPoses - 1) + " (" + std::to_string(merged) +
             " merged by latest-wins; each motion once: " + (once ? "yes" : "no") + "), " +
             std::to_string(f.unknown_client_rejoins) + " re-joins on unknown_client, " +
             std::to_string(sessions.size()) + " sessions, " + std::to_string(f.resent_poses) +
             " poses re-sent, " + std::to_string(f.repeated_answers) + " repeats dropped");
  return g_failures.load() == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 5 && std::string(argv[1]) == "silence") {
    g_port = std::stoi(argv[2]);
    return Silence(sweptccd::LoadKeyFile(argv[3]), argv[4]);
  }
  if (argc >= 4 && std::string(argv[1]) == "replace") {
    g_port = std::stoi(argv[2]);
    return Replace(sweptccd::LoadKeyFile(argv[3]));
  }
  if (argc >= 5 && std::string(argv[1]) == "reconnect") {
    g_port = std::stoi(argv[2]);
    return Reconnect(sweptccd::LoadKeyFile(argv[3]), argv[4]);
  }
  if (argc != 6) {
    std::fprintf(stderr,
                 "usage: ws_attack_tool PORT ROOM_KEY PER_ADDRESS HANDSHAKE_MS MAX_MESSAGE\n");
    return 2;
  }
  g_port = std::stoi(argv[1]);
  const int per_address = std::stoi(argv[3]);
  const int handshake_ms = std::stoi(argv[4]);
  const size_t max_message = std::stoul(argv[5]);
  struct Attack {
    const char* name;
    std::function<void()> run;
  };
  const Attack attacks[] = {
      {"flood", [&] { Flood(per_address); }},
      {"slowloris", [&] { Slowloris(handshake_ms); }},
      {"oversized", [&] { Oversized(max_message); }},
      {"malformed", [] { Malformed(); }},
      {"wrong_key", [] { WrongKey(); }},
      {"rate", [] { Rate(); }},
      {"never_reads", [] { NeverReads(); }},
  };
  // Concurrently: the door is hit by all of them at once.
  std::vector<std::thread> threads;
  for (const Attack& a : attacks) {
    threads.emplace_back([&a] {
      try {
        a.run();
      } catch (const std::exception& e) {
        Report(false, a.name, std::string("threw: ") + e.what());
      }
    });
  }
  for (auto& t : threads) t.join();
  std::printf("ws_attack_tool: %d failures\n", g_failures.load());
  return g_failures == 0 ? 0 : 1;
}
