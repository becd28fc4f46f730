// shared_world_tool: the shared world end to end (tests/service/e2e_shared_world.sh).
//
//   shared_world_tool write DIR
//     Writes a world (SPEC 8): DIR/arm.json (a two-link arm), DIR/alice.jsonl
//     (90 Hz), DIR/bob.jsonl (60 Hz, 5 ms later), DIR/carol.jsonl (72 Hz,
//     3 ms later), DIR/cube.obj and
//     DIR/cup.jsonl (a tracked cube at 30 Hz, 12 ms later), DIR/floor.obj
//     (just below the arms) and DIR/world.json naming them; and for `listen`
//     DIR/stream.jsonl (360 Hz, 20 s later), DIR/sim_alice.jsonl,
//     DIR/sim_bob.jsonl and DIR/sim_world.json.
//   shared_world_tool --key FILE listen URL DIR OFFLINE.jsonl
//     The checks of `play` while `sweptccd simulate-tracker` plays
//     DIR/stream.jsonl for alice (--client-rate alice=90) and bob
//     (--client-rate bob=60 --client-phase-us bob=5000, --spacing 0.25 0.05
//     0): against `sweptccd world` on DIR/sim_world.json (what `write`
//     computes it sends), and no rejection at all.
//   shared_world_tool --key FILE play URL DIR OFFLINE.jsonl
//     Publishes every sample of DIR/world.json in utime order at real-time
//     pace (tracker_pose_t for the avatars, object_pose_t for the cup, signed
//     with FILE), then one object pose of an unknown object ("ghost"); reads
//     contact_event_t, shared_contact_t and rejection_t (DecodeChecked, mac
//     verified) until every pair's shared entries are in (bounded: 30 s).
//     Checks: every environment event of a pair not merged by latest-wins
//     equals `sweptccd world`'s record (OFFLINE.jsonl: result, bracket,
//     first witness); every shared entry of such a pair not ended by the
//     timeout equals `sweptccd world`'s entry bit for bit; every such pair has exactly its offline
//     entries; the only rejection is one unknown_object for "ghost". Exit 0 when all hold.
//   shared_world_tool --key FILE play-ws URL PORT DIR OFFLINE.jsonl
//     `play` with alice a live client of the WebSocket door (127.0.0.1:PORT,
//     docs/WEBSOCKET.md: join with DIR/arm.json and her filter, poses over
//     the socket) while bob, carol and the cup stay on LCM: one room, two
//     doors. Alice's answers are read from the WebSocket, everyone else's
//     from LCM, all checked as `play` checks them; and every message of
//     alice's that LCM carries too must equal the WebSocket's field for
//     field (LCM encodings equal).
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "msgs/channels.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "sweptccd_client/tracker_pose.h"
#include "sweptccd_client/ws_client.h"

namespace {

using namespace sweptccd;
using json = nlohmann::json;

std::optional<MacKey> g_key;

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  if (!out) {
    std::fprintf(stderr, "shared_world_tool: cannot write %s\n", path.c_str());
    std::exit(2);
  }
}

// Which samples of a stream one client sends at its own rate and phase: the
// rule of simulate-tracker (ClientState::Takes in
// tools/simulate_tracker_command.cc), written again: ticks at the first
// utime + phase + m / rate; at each, the first sample at or after it.
class Ticks {
 public:
  Ticks(double rate_hz, double phase_us) : period_us_(1e6 / rate_hz), phase_us_(phase_us) {}
  bool Takes(int64_t utime) {
    if (!first_) first_ = utime;
    const double since = static_cast<double>(utime - *first_) - phase_us_;
    if (since < next_ * period_us_) return false;
    next_ = static_cast<int64_t>(std::floor(since / period_us_)) + 1;
    return true;
  }

 private:
  double period_us_, phase_us_;
  std::optional<int64_t> first_;
  int64_t next_ = 0;
};

// Files that also get a sample at a utime, each with the offset its positions get.
using ArmFilter =
    std::function<std::vector<std::pair<std::string, Eigen::Vector3d>>(int64_t utime)>;

int Write(const std::string& dir) {
  WriteText(dir + "/arm.json", R"({"name": "arm", "links": [
    {"name": "upper", "parent": null, "a": [0, 0, 0], "b": [0, 0.3, 0], "radius": 0.05},
    {"name": "fore", "parent": "upper", "a": [0, 0, 0], "b": [0.3, 0, 0], "radius": 0.04}]})");
  std::string cube = "";
  const double h = 0.08;
  for (int c = 0; c < 8; ++c) {
    cube += "v " + std::to_string((c & 1) ? h : -h) + " " + std::to_string((c & 2) ? h : -h) + " " +
            std::to_string((c & 4) ? h : -h) + "\n";
  }
  cube += "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";
  WriteText(dir + "/cube.obj", cube);
  // The floor 9 cm under the arms' mean height: their links (radius 4-5 cm)
  // wander onto it now and then, so the environment parts have contacts too.
  WriteText(dir + "/floor.obj",
            "v -10 -10 -0.09\nv 10 -10 -0.09\nv 10 10 -0.09\nv -10 10 -0.09\nf 1 2 3 4\n");
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0, 1);
  const int64_t start = 1'000'000, end = 2'500'000;
  // A stream from `start` to `until` (0: `end`).
  auto arm = [&](const std::string& file, Eigen::Vector3d center, int64_t phase, int64_t period,
                 int64_t shift = 0, ArmFilter keep = nullptr, int64_t until = 0) {
    std::string text;
    std::map<std::string, std::string> kept;  // Per keep() file.
    Eigen::Vector3d p = center;
    double angle = 0;
    for (int64_t t = start + phase; t <= (until > 0 ? until : end); t += period) {
      p += 0.02 * Eigen::Vector3d(n(rng), n(rng), n(rng)) + 0.1 * (center - p);
      angle += 0.15 * n(rng);
      const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
      const Eigen::Vector3d c = p + q * Eigen::Vector3d(0, 0.3, 0);
      auto line = [&](const Eigen::Vector3d& d) {
        char out[512];
        std::snprintf(out, sizeof out,
                      "{\"utime\": %lld, \"links\": [[%.17g, %.17g, %.17g, %.17g, %.17g, %.17g, "
                      "%.17g], [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g]]}\n",
                      static_cast<long long>(t + shift), p.x() + d.x(), p.y() + d.y(),
                      p.z() + d.z(), q.w(), q.x(), q.y(), q.z(), c.x() + d.x(), c.y() + d.y(),
                      c.z() + d.z(), q.w(), q.x(), q.y(), q.z());
        return std::string(out);
      };
      text += line(Eigen::Vector3d::Zero());
      if (keep) {
        for (const auto& [name, d] : keep(t + shift)) kept[name] += line(d);
      }
    }
    WriteText(dir + "/" + file, text);
    for (const auto& [name, lines] : kept) WriteText(dir + "/" + name, lines);
  };
  arm("alice.jsonl", {0, 0, 0}, 0, 11'111);
  arm("bob.jsonl", {0.25, 0.05, 0}, 5'000, 16'667);
  arm("carol.jsonl", {-0.2, 0.1, 0}, 3'000, 13'889);
  std::string cup;
  Eigen::Vector3d p(0.1, 0.25, 0);
  for (int64_t t = start + 12'000; t <= end; t += 33'333) {
    p += 0.03 * Eigen::Vector3d(n(rng), n(rng), n(rng)) + 0.2 * (Eigen::Vector3d(0.1, 0.25, 0) - p);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3 * n(rng), Eigen::Vector3d::UnitX()));
    char line[512];
    std::snprintf(
        line, sizeof line,
        "{\"utime\": %lld, \"pose\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g]}\n",
        static_cast<long long>(t), p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
    cup += line;
  }
  WriteText(dir + "/cup.jsonl", cup);
  // simulate-tracker's own rates and phases: one 360 Hz stream, 20 s later
  // (DIR/stream.jsonl), and what it sends of it for alice (--client-rate
  // alice=90) and bob (--client-rate bob=60 --client-phase-us bob=5000,
  // moved by --spacing 0.25 0.05 0), as DIR/sim_alice.jsonl and
  // DIR/sim_bob.jsonl, named by DIR/sim_world.json. 3.5 s long (about 525
  // pairs): `listen` compares at least 200 entries of pairs latest-wins did
  // not merge, and a player or daemon stalled for 0.5 s on a loaded machine
  // merges the ~75 pairs sent meanwhile (at 1.5 s, 223 pairs, 151-192 were left).
  Ticks alice_ticks(90, 0), bob_ticks(60, 5000);
  arm(
      "stream.jsonl", {0, 0, 0}, 0, 2'778, 20'000'000,
      [&](int64_t t) {
        std::vector<std::pair<std::string, Eigen::Vector3d>> to;
        if (alice_ticks.Takes(t)) to.push_back({"sim_alice.jsonl", Eigen::Vector3d::Zero()});
        if (bob_ticks.Takes(t)) to.push_back({"sim_bob.jsonl", Eigen::Vector3d(0.25, 0.05, 0)});
        return to;
      },
      start + 3'500'000);
  // The filters are those of e2e_shared_world.sh's configuration.
  WriteText(dir + "/sim_world.json", R"({
  "avatars": [{"id": "alice", "skeleton": "arm.json", "poses": "sim_alice.jsonl",
               "ignore": [{"link": "upper", "entity": "cup"}]},
              {"id": "bob", "skeleton": "arm.json", "poses": "sim_bob.jsonl",
               "ignore": [{"link": "fore", "entity": "alice", "other_link": "fore"}]}],
  "env": ["floor.obj"]})");
  WriteText(dir + "/world.json", R"({
  "avatars": [{"id": "alice", "skeleton": "arm.json", "poses": "alice.jsonl",
               "ignore": [{"link": "upper", "entity": "cup"}]},
              {"id": "bob", "skeleton": "arm.json", "poses": "bob.jsonl",
               "ignore": [{"link": "fore", "entity": "alice", "other_link": "fore"}]},
              {"id": "carol", "skeleton": "arm.json", "poses": "carol.jsonl"}],
  "objects": [{"id": "cup", "mesh": "cube.obj", "poses": "cup.jsonl"}],
  "env": ["floor.obj"]})");
  return 0;
}

template <class T>
void Send(lcm::LCM& lcm, const std::string& channel, const T& m) {
  const std::vector<uint8_t> bytes = EncodeSigned(m, g_key ? &*g_key : nullptr);
  lcm.publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size()));
}

// One entry of a shared_contact_t, with its message's pair fields.
struct LiveEntry : shared_entry_t {
  std::string client_id;
  int64_t pair = 0, seq0 = 0, seq1 = 0, utime0 = 0, utime1 = 0;
};

struct Receiver {
  // A WebSocket client's id: LCM's copies of its messages are kept apart
  // (compared with what the socket delivers), its answers come from `inbox`.
  std::string ws_id;
  std::vector<contact_event_t> lcm_ws_contacts;
  std::vector<shared_contact_t> lcm_ws_shared;
  std::vector<contact_event_t> contacts;
  std::vector<LiveEntry> shared;  // Every entry of every message.
  int64_t shared_messages = 0;
  std::vector<rejection_t> rejections;
  int bad = 0;
  template <class T>
  bool Take(const lcm::ReceiveBuffer* rbuf, T* out) {
    DecodeResult<T> d = DecodeChecked<T>(rbuf->data, rbuf->data_size, WireLimits{});
    if (!d.ok() || (g_key && !VerifyEncoded(rbuf->data, rbuf->data_size, *g_key))) {
      ++bad;
      return false;
    }
    *out = std::move(*d.message);
    return true;
  }
  void OnContact(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    contact_event_t m;
    if (!Take(rbuf, &m)) return;
    if (!ws_id.empty() && m.client_id == ws_id) {
      lcm_ws_contacts.push_back(m);
    } else {
      contacts.push_back(m);
    }
  }
  void OnShared(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    shared_contact_t m;
    if (!Take(rbuf, &m)) return;
    if (!ws_id.empty() && m.client_id == ws_id) {
      lcm_ws_shared.push_back(m);
      return;
    }
    AddShared(m);
  }
  void AddShared(const shared_contact_t& m) {
    ++shared_messages;
    for (const shared_entry_t& e : m.entries) {
      LiveEntry x;
      static_cast<shared_entry_t&>(x) = e;
      x.client_id = m.client_id;
      x.pair = m.pair, x.seq0 = m.seq0, x.seq1 = m.seq1, x.utime0 = m.utime0, x.utime1 = m.utime1;
      shared.push_back(std::move(x));
    }
  }
  void OnReject(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    rejection_t m;
    if (Take(rbuf, &m)) rejections.push_back(m);
  }
};

// Per-link brackets compared (offline written with --per-link).
int g_link_brackets = 0;

// The differences between a live entry and the offline one ("" if none).
// When the offline entry has `links` (sweptccd world --per-link), the live
// entry's per-link brackets are compared too, each field bit for bit.
std::string Diff(const LiveEntry& s, const json& o) {
  std::string d;
  auto eq = [&](const char* what, double live, double off) {
    if (!(live == off)) d += std::string(" ") + what;
  };
  if (o.contains("links")) {
    const json& links = o["links"];
    if (s.links.size() != links.size() || s.num_links != static_cast<int32_t>(s.links.size())) {
      return d + " links";
    }
    for (size_t i = 0; i < s.links.size(); ++i) {
      const entity_link_bracket_t& b = s.links[i];
      const json& w = links[i];
      eq("links.link", b.link, w["link"].get<double>());
      eq("links.s_lo", b.s_lo, w["s_lo"].get<double>());
      eq("links.s_hi", b.s_hi, w["s_hi"].get<double>());
      eq("links.t_lo", b.t_lo, w["t_lo"].get<double>());
      eq("links.t_hi", b.t_hi, w["t_hi"].get<double>());
      if (b.initially_colliding != w["initially_colliding"].get<bool>()) d += " links.initially";
      if (b.undecided != w["undecided"].get<bool>()) d += " links.undecided";
      if (static_cast<bool>(b.has_witness) != w.contains("contact")) {
        d += " links.witness";
      } else if (b.has_witness) {
        const json& c = w["contact"];
        eq("links.witness.link", b.witness.link, c["link"].get<double>());
        eq("links.witness.s", b.witness.s, c["s"].get<double>());
        eq("links.witness.separation", b.witness.separation, c["separation"].get<double>());
        for (int k = 0; k < 3; ++k) {
          eq("links.witness.point_link", b.witness.point_link[k], c["point_link"][k].get<double>());
          eq("links.witness.point_other", b.witness.point_other[k],
             c["point_other"][k].get<double>());
        }
      }
      ++g_link_brackets;
    }
  } else if (!s.links.empty()) {
    d += " links (none offline)";
  }
  eq("t_from", static_cast<double>(s.t_from), o["window"][0].get<double>());
  eq("t_to", static_cast<double>(s.t_to), o["window"][1].get<double>());
  const bool contact = o["result"] == "contact";
  if ((s.result == 1) != contact) return d + " result";
  if (s.initially_colliding != o["initially_colliding"].get<bool>()) d += " initially_colliding";
  if (s.undecided != o["undecided"].get<bool>()) d += " undecided";
  if (!contact) return d;
  eq("s_lo", s.s_lo, o["s_lo"].get<double>());
  eq("s_hi", s.s_hi, o["s_hi"].get<double>());
  eq("t_lo", s.t_lo, o["t_lo"].get<double>());
  eq("t_hi", s.t_hi, o["t_hi"].get<double>());
  if (s.contacts.size() != o["contacts"].size()) return d + " contacts";
  for (size_t i = 0; i < s.contacts.size(); ++i) {
    const entity_contact_t& c = s.contacts[i];
    const json& w = o["contacts"][i];
    eq("link", c.link, w["link"].get<double>());
    eq("other_link", c.other_link, w.contains("other_link") ? w["other_link"].get<double>() : -1);
    eq("triangle", static_cast<double>(c.triangle),
       w.contains("triangle") ? w["triangle"].get<double>() : -1);
    eq("s", c.s, w["s"].get<double>());
    for (int k = 0; k < 3; ++k) {
      eq("point_link", c.point_link[k], w["point_link"][k].get<double>());
      eq("point_other", c.point_other[k], w["point_other"][k].get<double>());
      eq("normal", c.normal[k], w["normal"][k].get<double>());
    }
    eq("separation", c.separation, w["separation"].get<double>());
  }
  return d;
}

// Offline entries by (avatar, utime0, utime1) -> entity -> entry; the
// record itself (its environment part) under the entity "" (no id is empty).
using Offline = std::map<std::tuple<std::string, int64_t, int64_t>, std::map<std::string, json>>;

Offline LoadOffline(const std::string& offline_path) {
  Offline offline;
  std::ifstream in(offline_path);
  std::string line;
  while (std::getline(in, line)) {
    json r = json::parse(line);
    auto& e = offline[{r["avatar"].get<std::string>(), r["utime0"].get<int64_t>(),
                       r["utime1"].get<int64_t>()}];
    for (const json& o : r["others"]) e[o["entity"].get<std::string>()] = o;
    r.erase("others");
    e[""] = std::move(r);
  }
  return offline;
}

// Where the daemon's environment event differs from `sweptccd world`'s
// record of the same pair: the result, and for a contact the bracket (s and
// printed t, bit for bit), initially_colliding, and the first witness's
// link, object, triangle and s.
std::string EnvDiff(const contact_event_t& c, const json& r) {
  std::string d;
  const std::string result = r["result"].get<std::string>();
  const int want = result == "contact" ? 1 : result == "free" ? 0 : 2;
  if (c.result != want) return " result " + std::to_string(c.result) + " vs " + result;
  if (want != 1) return d;
  if (c.s_lo != r["s_lo"].get<double>() || c.s_hi != r["s_hi"].get<double>()) d += " s";
  if (c.t_lo != r["t_lo"].get<double>() || c.t_hi != r["t_hi"].get<double>()) d += " t";
  if (c.initially_colliding != r["initially_colliding"].get<bool>()) d += " initially_colliding";
  const json& w = r["contacts"];
  if (c.num_contacts < 1 || w.empty()) return d + " witnesses";
  const contact_record_t& k = c.contacts[0];
  if (k.link != w[0]["link"].get<int>() || k.object != w[0]["object"].get<int>() ||
      k.triangle != w[0]["triangle"].get<int64_t>() || k.s != w[0]["s"].get<double>()) {
    d += " witness";
  }
  return d;
}

// Each subscription holds kLcmQueueCapacity messages, as the client
// library's do: with LCM's default (30) the reader thread drops what the
// play's thread (sleeping between sends) has not taken yet. After a stopped
// daemon caught up in a burst, LCM's copies of alice's messages numbered
// fewer than the WebSocket's (267 against 269) and LCM clients' pairs were
// "never published": inferred to be this reader's losses.
void Subscribe(lcm::LCM& lcm, Receiver* rx) {
  for (lcm::Subscription* s : {lcm.subscribe(kContactChannel, &Receiver::OnContact, rx),
                               lcm.subscribe(kSharedContactChannel, &Receiver::OnShared, rx),
                               lcm.subscribe(kRejectChannel, &Receiver::OnReject, rx)}) {
    if (s == nullptr) throw std::runtime_error("cannot subscribe to the daemon's channels");
    s->setQueueCapacity(kLcmQueueCapacity);
  }
}

// What a run must show: each avatar's last seq answered; the one ghost
// rejection (or none); at least so many entries compared and contacts.
struct Expect {
  std::map<std::string, int64_t> last_seq;
  bool ghost = true;
  int min_compared = 200, min_contacts = 10;
};

int Check(lcm::LCM& lcm, Receiver& rx, const Offline& offline, const Expect& expect);

// Messages a WebSocket client received (its own thread), merged into the
// Receiver by the checking loop.
struct WsInbox {
  std::mutex mutex;
  std::vector<contact_event_t> contacts, all_contacts;
  std::vector<shared_contact_t> shared, all_shared;
  std::vector<rejection_t> rejections;
  void MergeInto(Receiver* rx) {
    std::lock_guard<std::mutex> lock(mutex);
    for (auto& c : contacts) rx->contacts.push_back(c);
    for (auto& m : shared) rx->AddShared(m);
    for (auto& r : rejections) rx->rejections.push_back(r);
    contacts.clear(), shared.clear(), rejections.clear();
  }
};
std::function<void()> g_merge = [] {};

template <class T>
std::vector<uint8_t> Bytes(T m) {
  std::fill(std::begin(m.mac), std::end(m.mac), 0);
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

int Play(const std::string& url, const std::string& dir, const std::string& offline_path,
         int ws_port = 0) {
  lcm::LCM lcm(url);
  if (!lcm.good()) return 2;
  Receiver rx;
  Subscribe(lcm, &rx);
  // Alice through the WebSocket door.
  std::unique_ptr<WsLiveClient> ws;
  WsInbox inbox;
  if (ws_port > 0) {
    rx.ws_id = "alice";
    WsLiveClient::Options o;
    o.port = static_cast<uint16_t>(ws_port);
    o.client_id = "alice";
    o.room_key = g_key;
    o.skeleton = LoadSkeletonFile(dir + "/arm.json");
    o.ignore_entities = {{"upper", "cup", ""}};
    o.reconnect = false;
    ws = std::make_unique<WsLiveClient>(o);
    ws->OnContact([&](const contact_event_t& e) {
      std::lock_guard<std::mutex> lock(inbox.mutex);
      inbox.contacts.push_back(e);
      inbox.all_contacts.push_back(e);
    });
    ws->OnSharedContact([&](const shared_contact_t& e) {
      std::lock_guard<std::mutex> lock(inbox.mutex);
      inbox.shared.push_back(e);
      inbox.all_shared.push_back(e);
    });
    ws->OnRejection([&](const rejection_t& r) {
      std::lock_guard<std::mutex> lock(inbox.mutex);
      inbox.rejections.push_back(r);
    });
    ws->OnError([](const std::string& code, const std::string& message) {
      std::printf("websocket error %s: %s\n", code.c_str(), EscapeForDisplay(message).c_str());
    });
    const JoinResult joined = ws->Join();
    if (!joined.ok()) {
      std::printf("FAIL: alice's WebSocket join: %d %s\n", joined.reason, joined.message.c_str());
      return 1;
    }
    std::printf("shared_world_tool: alice joined over the WebSocket door, session %lld\n",
                static_cast<long long>(joined.session));
    g_merge = [&] { inbox.MergeInto(&rx); };
  }
  const Offline offline = LoadOffline(offline_path);
  // The raw lines of the files `write` made: the daemon normalises what it
  // receives exactly as `sweptccd world` normalises what it reads.
  struct Sample {
    int64_t utime;
    int kind;  // 0 avatar, 1 object.
    std::string id;
    int64_t seq;
    json values;
  };
  std::vector<Sample> order;
  for (const auto& [id, kind] :
       {std::pair<std::string, int>{"alice", 0}, {"bob", 0}, {"carol", 0}, {"cup", 1}}) {
    std::ifstream in(dir + "/" + id + ".jsonl");
    std::string line;
    int64_t seq = 0;
    while (std::getline(in, line)) {
      const json j = json::parse(line);
      order.push_back(
          {j["utime"].get<int64_t>(), kind, id, seq++, kind == 0 ? j["links"] : j["pose"]});
    }
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const Sample& x, const Sample& y) { return x.utime < y.utime; });
  std::map<std::string, int64_t> last_seq;
  const auto t0 = std::chrono::steady_clock::now();
  const int64_t u_first = order.front().utime;
  for (const Sample& x : order) {
    std::this_thread::sleep_until(t0 + std::chrono::microseconds(x.utime - u_first));
    if (x.kind == 0) {
      tracker_pose_t m = TrackerPoseOfLine(json{{"utime", x.utime}, {"links", x.values}}.dump());
      m.client_id = x.id;
      m.session = 1;
      m.seq = x.seq;
      if (ws && x.id == "alice") {
        if (!ws->PublishPose(m)) {
          std::printf("FAIL: alice's pose %lld not sent (not joined)\n",
                      static_cast<long long>(m.seq));
          return 1;
        }
      } else {
        Send(lcm, kPoseChannel, m);
      }
      last_seq[x.id] = m.seq;
    } else {
      object_pose_t m{};
      m.utime = x.utime;
      m.object_id = x.id;
      m.session = 1;
      m.seq = x.seq;
      for (int c = 0; c < 3; ++c) m.position[c] = x.values[c].get<double>();
      for (int c = 0; c < 4; ++c) m.orientation[c] = x.values[3 + c].get<double>();
      Send(lcm, kObjectPoseChannel, m);
    }
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  object_pose_t ghost{};
  ghost.utime = order.back().utime;
  ghost.object_id = "ghost";
  ghost.session = 1;
  ghost.seq = 1;
  ghost.orientation[0] = 1;
  Send(lcm, kObjectPoseChannel, ghost);
  Expect expect;
  expect.last_seq = last_seq;
  const int result = Check(lcm, rx, offline, expect);
  if (!ws) return result;
  // LCM's copies of alice's messages equal the WebSocket's, field for field.
  int failures = 0;
  std::lock_guard<std::mutex> lock(inbox.mutex);
  auto by_pair = [](const auto& x, const auto& y) { return x.pair < y.pair; };
  std::stable_sort(inbox.all_contacts.begin(), inbox.all_contacts.end(), by_pair);
  std::stable_sort(rx.lcm_ws_contacts.begin(), rx.lcm_ws_contacts.end(), by_pair);
  if (inbox.all_contacts.size() != rx.lcm_ws_contacts.size()) {
    std::printf("FAIL: alice: %zu contact events over the WebSocket, %zu over LCM\n",
                inbox.all_contacts.size(), rx.lcm_ws_contacts.size());
    ++failures;
  } else {
    for (size_t i = 0; i < inbox.all_contacts.size(); ++i) {
      if (Bytes(inbox.all_contacts[i]) != Bytes(rx.lcm_ws_contacts[i])) {
        std::printf("FAIL: alice pair %lld: the WebSocket's contact event differs from LCM's\n",
                    static_cast<long long>(inbox.all_contacts[i].pair));
        ++failures;
      }
    }
  }
  auto key = [](const shared_contact_t& m) {
    return std::make_tuple(m.pair, m.entries.empty() ? std::string() : m.entries[0].entity);
  };
  auto by_key = [&](const shared_contact_t& x, const shared_contact_t& y) {
    return key(x) < key(y);
  };
  std::stable_sort(inbox.all_shared.begin(), inbox.all_shared.end(), by_key);
  std::stable_sort(rx.lcm_ws_shared.begin(), rx.lcm_ws_shared.end(), by_key);
  if (inbox.all_shared.size() != rx.lcm_ws_shared.size()) {
    std::printf("FAIL: alice: %zu shared messages over the WebSocket, %zu over LCM\n",
                inbox.all_shared.size(), rx.lcm_ws_shared.size());
    ++failures;
  } else {
    for (size_t i = 0; i < inbox.all_shared.size(); ++i) {
      if (Bytes(inbox.all_shared[i]) != Bytes(rx.lcm_ws_shared[i])) {
        std::printf("FAIL: alice pair %lld: the WebSocket's shared message differs from LCM's\n",
                    static_cast<long long>(inbox.all_shared[i].pair));
        ++failures;
      }
    }
  }
  int alice_contacts = 0;
  for (const auto& c : inbox.all_contacts) alice_contacts += c.result == 1;
  std::printf(
      "shared_world_tool: alice over the WebSocket: %zu contact events (%d contacts), %zu "
      "shared messages, all equal to LCM's copies; %d failures\n",
      inbox.all_contacts.size(), alice_contacts, inbox.all_shared.size(), failures);
  if (inbox.all_contacts.size() < 50 || alice_contacts < 1) {
    std::printf("FAIL: too few of alice's answers over the WebSocket\n");
    ++failures;
  }
  ws->Leave();
  return result == 0 && failures == 0 ? 0 : 1;
}

// Listens while `sweptccd simulate-tracker` plays DIR/stream.jsonl for alice
// and bob at their own rates and phases; the samples it sends are
// DIR/sim_alice.jsonl and DIR/sim_bob.jsonl (seq 0, 1, ... in each).
int Listen(const std::string& url, const std::string& dir, const std::string& offline_path) {
  lcm::LCM lcm(url);
  if (!lcm.good()) return 2;
  Receiver rx;
  Subscribe(lcm, &rx);
  const Offline offline = LoadOffline(offline_path);
  Expect expect;
  expect.ghost = false;
  for (const std::string id : {"alice", "bob"}) {
    std::ifstream in(dir + "/sim_" + id + ".jsonl");
    std::string line;
    int64_t lines = 0;
    while (std::getline(in, line)) ++lines;
    expect.last_seq[id] = lines - 1;
  }
  std::printf("shared_world_tool: listening\n");
  std::fflush(stdout);
  return Check(lcm, rx, offline, expect);
}

int Check(lcm::LCM& lcm, Receiver& rx, const Offline& offline, const Expect& expect) {
  // Until every pair's last pose is answered and each answered pair not
  // merged by latest-wins has all its offline entries (bounded).
  auto expected_keys = [&] {
    std::set<std::tuple<std::string, int64_t, std::string>> keys;
    for (const contact_event_t& c : rx.contacts) {
      if (c.seq1 - c.seq0 != 1) continue;  // Merged by latest-wins.
      const auto it = offline.find({c.client_id, c.utime0, c.utime1});
      if (it == offline.end()) continue;
      for (const auto& [entity, o] : it->second) {
        // A live client's entry that only E's silence can close (E's samples
        // end inside the pair) may be dropped with the client when it is
        // dropped for silence itself at the same time (a configured one
        // stays and gets it ended_by_timeout).
        if (c.client_id == rx.ws_id && o.contains("window") &&
            o["window"][1].get<int64_t>() < c.utime1) {
          continue;
        }
        if (!entity.empty()) keys.insert({c.client_id, c.pair, entity});
      }
    }
    return keys;
  };
  auto done = [&] {
    std::map<std::string, int64_t> answered;
    for (const contact_event_t& c : rx.contacts) {
      answered[c.client_id] = std::max(answered[c.client_id], c.seq1);
    }
    if (answered != expect.last_seq) return false;
    std::set<std::tuple<std::string, int64_t, std::string>> got;
    for (const LiveEntry& s : rx.shared) got.insert({s.client_id, s.pair, s.entity});
    for (const auto& k : expected_keys()) {
      if (!got.count(k)) return false;
    }
    return !expect.ghost || !rx.rejections.empty();
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    lcm.handleTimeout(50);
    g_merge();
  }
  // Anything more (a duplicate would show now).
  for (int i = 0; i < 10; ++i) {
    lcm.handleTimeout(50);
    g_merge();
  }

  int failures = 0;
  if (!done()) {
    std::printf("FAIL: not every pair and shared entry arrived within 30 s\n");
    ++failures;
  }
  std::set<std::tuple<std::string, int64_t, std::string>> seen;
  int compared = 0, cut = 0, merged = 0, waited = 0, contacts = 0;
  // Every environment event of a pair not merged by latest-wins equals the
  // offline record's environment part.
  int env_compared = 0, env_contacts = 0;
  for (const contact_event_t& c : rx.contacts) {
    if (c.seq1 - c.seq0 != 1) continue;
    const auto it = offline.find({c.client_id, c.utime0, c.utime1});
    if (it == offline.end() || !it->second.count("")) {
      std::printf("FAIL: %s [%lld, %lld]: no such offline record\n",
                  EscapeForDisplay(c.client_id).c_str(), static_cast<long long>(c.utime0),
                  static_cast<long long>(c.utime1));
      ++failures;
      continue;
    }
    const std::string d = EnvDiff(c, it->second.at(""));
    if (!d.empty()) {
      std::printf("FAIL: %s [%lld, %lld] environment differs:%s\n",
                  EscapeForDisplay(c.client_id).c_str(), static_cast<long long>(c.utime0),
                  static_cast<long long>(c.utime1), d.c_str());
      ++failures;
    }
    ++env_compared;
    env_contacts += c.result == 1;
  }
  if (env_compared < expect.min_compared / 2 || env_contacts < expect.min_contacts) {
    std::printf("FAIL: only %d environment events compared (%d contacts)\n", env_compared,
                env_contacts);
    ++failures;
  }
  for (const LiveEntry& s : rx.shared) {
    if (!seen.insert({s.client_id, s.pair, s.entity}).second) {
      std::printf("FAIL: %s pair %lld against %s published twice\n",
                  EscapeForDisplay(s.client_id).c_str(), static_cast<long long>(s.pair),
                  EscapeForDisplay(s.entity).c_str());
      ++failures;
    }
    waited += s.waited_us > 0;
    if (s.ended_by_timeout) {
      ++cut;
      continue;
    }
    if (s.seq1 - s.seq0 != 1) {
      ++merged;
      continue;
    }
    const auto it = offline.find({s.client_id, s.utime0, s.utime1});
    const std::string entity = s.entity;
    if (it == offline.end() || !it->second.count(entity)) {
      std::printf("FAIL: %s [%lld, %lld] against %s: no such offline entry\n",
                  EscapeForDisplay(s.client_id).c_str(), static_cast<long long>(s.utime0),
                  static_cast<long long>(s.utime1), EscapeForDisplay(entity).c_str());
      ++failures;
      continue;
    }
    const std::string d = Diff(s, it->second.at(entity));
    if (!d.empty()) {
      std::printf("FAIL: %s [%lld, %lld] against %s differs:%s\n", s.client_id.c_str(),
                  static_cast<long long>(s.utime0), static_cast<long long>(s.utime1),
                  entity.c_str(), d.c_str());
      ++failures;
    }
    ++compared;
    contacts += s.result == 1;
  }
  for (const auto& k : expected_keys()) {
    if (!seen.count(k)) {
      std::printf("FAIL: %s pair %lld against %s never published\n", std::get<0>(k).c_str(),
                  static_cast<long long>(std::get<1>(k)), std::get<2>(k).c_str());
      ++failures;
    }
  }
  if (!expect.ghost && !rx.rejections.empty()) {
    std::printf("FAIL: %zu rejections, expected none\n", rx.rejections.size());
    ++failures;
  } else if (expect.ghost &&
             (rx.rejections.size() != 1 || rx.rejections[0].reason != "unknown_object" ||
              rx.rejections[0].client_id != "ghost")) {
    std::printf("FAIL: expected exactly one unknown_object rejection for 'ghost', got %zu\n",
                rx.rejections.size());
    for (const rejection_t& r : rx.rejections) {
      std::printf("  %s %s\n", r.reason.c_str(), EscapeForDisplay(r.message).c_str());
    }
    ++failures;
  }
  if (rx.bad > 0) {
    std::printf("FAIL: %d messages did not decode or verify\n", rx.bad);
    ++failures;
  }
  // The run must compare something real: most entries, some contacts (and,
  // in per-link mode, some per-link brackets).
  if (compared < expect.min_compared || contacts < expect.min_contacts) {
    std::printf("FAIL: only %d entries compared (%d contacts)\n", compared, contacts);
    ++failures;
  }
  bool offline_per_link = false;
  for (const auto& [key, entries] : offline) {
    for (const auto& [entity, o] : entries) {
      if (!entity.empty()) offline_per_link = offline_per_link || o.contains("links");
    }
  }
  if (offline_per_link && g_link_brackets < expect.min_contacts) {
    std::printf("FAIL: per-link mode, only %d per-link brackets compared\n", g_link_brackets);
    ++failures;
  }
  std::printf(
      "shared_world_tool: %zu pairs (%d environment events equal to sweptccd world, %d "
      "contacts), %zu shared entries in %lld messages: %d equal to sweptccd "
      "world (%d contacts, %d per-link brackets), %d ended by timeout, %d of merged pairs, %d "
      "waited; %d failures\n",
      rx.contacts.size(), env_compared, env_contacts, rx.shared.size(),
      static_cast<long long>(rx.shared_messages), compared, contacts, g_link_brackets, cut, merged,
      waited, failures);
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() >= 2 && args[0] == "--key") {
    g_key = LoadKeyFile(args[1]);
    args.erase(args.begin(), args.begin() + 2);
  }
  try {
    if (args.size() == 2 && args[0] == "write") return Write(args[1]);
    if (args.size() == 4 && args[0] == "play") return Play(args[1], args[2], args[3]);
    if (args.size() == 4 && args[0] == "listen") return Listen(args[1], args[2], args[3]);
    if (args.size() == 5 && args[0] == "play-ws") {
      return Play(args[1], args[3], args[4], std::stoi(args[2]));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "shared_world_tool: %s\n", e.what());
    return 2;
  }
  std::fprintf(
      stderr,
      "usage: shared_world_tool write DIR | [--key FILE] (play | listen) URL DIR OFFLINE\n");
  return 2;
}
