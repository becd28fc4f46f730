// Clients of one room through room discovery and failover (docs/DEPLOY.md),
// for tests/service/fleet/e2e_failover.sh: N WsLiveClients find room ROOM
// through the Agones allocator (stand-in) and stream the same walk at RATE
// Hz under ids c0..c{N-1}; the script kills the room's server and starts a
// replacement elsewhere while they stream. At the end, per client, the
// answered pairs (seq0, seq1) must tile the walk: the first starts at pose 0,
// each starts where the one before ended, the last ends at the last pose (no
// motion unanswered, none answered twice); each pair of consecutive poses
// equals `sweptccd query`'s record (EXPECTED). A pair over more poses is the
// service's latest-wins under load (docs/SERVICE.md: the motion from the last
// answered pose is covered, one skip counted), counted and printed. Every
// answer must come from the instance the client had joined. Prints one line per join
// ("join CLIENT instance I session S wall W") and per client a summary; the
// script checks times against the stand-ins' records.
//   failover_tool ALLOCATOR_URL ROOM SCENE ROOM_KEY CA_PEM SKELETON POSES EXPECTED N RATE
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "msgs/signing.h"
#include "sweptccd_client/room_resolver.h"
#include "sweptccd_client/tracker_pose.h"
#include "sweptccd_client/ws_client.h"

namespace {

using namespace sweptccd;
using Clock = std::chrono::steady_clock;

double Wall() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::vector<nlohmann::json> ReadLines(const std::string& path) {
  std::vector<nlohmann::json> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  }
  return out;
}

// The query record equal to the event? (result; for a contact s_lo, s_hi
// bit-equal and initially_colliding), as e2e_tool's lock-step comparison.
bool Same(const contact_event_t& e, const nlohmann::json& want) {
  const int w = want["result"] == "contact" ? 1 : want["result"] == "free" ? 0 : 2;
  if (e.result != w) return false;
  if (w != 1) return true;
  return e.s_lo == want["s_lo"].get<double>() && e.s_hi == want["s_hi"].get<double>() &&
         e.initially_colliding == want["initially_colliding"].get<bool>();
}

struct Tally {
  std::mutex mutex;
  std::map<int64_t, int> answers;                  // seq1 -> times delivered
  std::vector<std::pair<int64_t, int64_t>> pairs;  // (seq0, seq1) as delivered
  int64_t mismatches = 0, wrong_instance = 0, contacts = 0;
  int64_t joined_instance = 0;
  std::vector<int64_t> instances;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 11) {
    std::fprintf(stderr,
                 "usage: failover_tool ALLOCATOR_URL ROOM SCENE ROOM_KEY CA_PEM SKELETON POSES "
                 "EXPECTED N RATE\n");
    return 2;
  }
  AgonesAllocatorOptions ao;
  ao.url = argv[1];
  const std::string room = argv[2];
  ao.fleet_labels = {{"sweptccd.dev/scene", argv[3]}};
  ao.timeout_s = 1.0;
  const MacKey key = LoadKeyFile(argv[4]);
  const Skeleton skeleton = LoadSkeletonFile(argv[6]);
  const std::vector<nlohmann::json> poses = ReadLines(argv[7]);
  const std::vector<nlohmann::json> expected = ReadLines(argv[8]);
  const int n = std::stoi(argv[9]);
  const double rate = std::stod(argv[10]);
  if (poses.size() < 2 || expected.size() != poses.size() - 1) {
    std::fprintf(stderr, "failover_tool: %zu poses but %zu expected records\n", poses.size(),
                 expected.size());
    return 2;
  }
  auto resolver = std::make_shared<AgonesAllocatorResolver>(ao);
  std::vector<std::unique_ptr<WsLiveClient>> clients;
  std::vector<std::unique_ptr<Tally>> tallies;
  std::mutex print;
  for (int c = 0; c < n; ++c) {
    WsLiveClient::Options o;
    o.client_id = "c" + std::to_string(c);
    o.room_key = key;
    o.skeleton = skeleton;
    o.resolver = resolver;
    o.room = room;
    o.ca_file = argv[5];
    o.heartbeat_timeout_s = 0.8;  // The rooms' status_period_s is 0.2.
    o.max_backoff_s = 0.25;
    o.connect_timeout_s = 0.5;
    o.join_timeout_s = 10;
    tallies.push_back(std::make_unique<Tally>());
    Tally* t = tallies.back().get();
    auto client = std::make_unique<WsLiveClient>(o);
    WsLiveClient* raw = client.get();
    client->OnJoinReply([t, raw, &print, id = o.client_id](const join_reply_t& r) {
      if (r.reason != 0) return;
      {
        std::lock_guard<std::mutex> lock(t->mutex);
        t->joined_instance = r.instance;
        t->instances.push_back(r.instance);
      }
      std::lock_guard<std::mutex> lock(print);
      std::printf("join %s instance %lld session %lld wall %.6f door %s\n", id.c_str(),
                  static_cast<long long>(r.instance), static_cast<long long>(r.session), Wall(),
                  raw->failover().door.c_str());
      std::fflush(stdout);
    });
    client->OnContact([t, raw, &expected](const contact_event_t& e) {
      std::lock_guard<std::mutex> lock(t->mutex);
      ++t->answers[e.seq1];
      t->pairs.push_back({e.seq0, e.seq1});
      if (raw->instance() != t->joined_instance) ++t->wrong_instance;
      if (e.seq1 < 1 || e.seq1 > static_cast<int64_t>(expected.size()) || e.seq0 >= e.seq1 ||
          (e.seq0 == e.seq1 - 1 && !Same(e, expected[static_cast<size_t>(e.seq1 - 1)]))) {
        ++t->mismatches;
      }
      if (e.result == 1) ++t->contacts;
    });
    clients.push_back(std::move(client));
  }
  for (auto& c : clients) {
    const JoinResult r = c->Join();
    if (!r.ok()) {
      std::fprintf(stderr, "failover_tool: %s did not join: %s\n", c->client_id().c_str(),
                   r.message.c_str());
      return 1;
    }
  }
  std::printf("streaming %zu poses x %d clients at %g Hz\n", poses.size(), n, rate);
  std::fflush(stdout);
  const auto period = std::chrono::duration<double>(1.0 / rate);
  auto next = Clock::now();
  for (size_t k = 0; k < poses.size(); ++k) {
    for (auto& c : clients) {
      tracker_pose_t p = TrackerPoseOfLine(poses[k].dump());
      p.seq = static_cast<int64_t>(k);
      if (!c->PublishPose(p)) {
        std::fprintf(stderr, "failover_tool: %s refused pose %zu\n", c->client_id().c_str(), k);
      }
    }
    next += std::chrono::duration_cast<Clock::duration>(period);
    std::this_thread::sleep_until(next);
  }
  const size_t pairs = poses.size() - 1;
  const int64_t last = static_cast<int64_t>(pairs);
  const auto deadline = Clock::now() + std::chrono::seconds(15);
  for (;;) {
    size_t done = 0;
    for (auto& t : tallies) {
      std::lock_guard<std::mutex> lock(t->mutex);
      if (t->answers.count(last)) ++done;
    }
    if (done == tallies.size() || Clock::now() > deadline) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  int failures = 0;
  for (int c = 0; c < n; ++c) {
    Tally& t = *tallies[c];
    std::lock_guard<std::mutex> lock(t.mutex);
    // The tiling: sorted by seq0, each pair starts where the previous ended.
    std::vector<std::pair<int64_t, int64_t>> sorted = t.pairs;
    std::sort(sorted.begin(), sorted.end());
    int64_t at = 0, merged = 0, consecutive = 0;
    std::string gaps;
    for (const auto& [seq0, seq1] : sorted) {
      if (seq0 != at && gaps.size() < 200) {
        gaps += " " + std::to_string(seq0) + (seq0 < at ? "(again)" : "(after a gap)");
      }
      at = std::max(at, seq1);
      (seq1 == seq0 + 1 ? consecutive : merged) += 1;
    }
    if (at != last && gaps.size() < 200) gaps += " ends at " + std::to_string(at);
    int64_t twice = 0;
    for (const auto& [seq1, times] : t.answers) twice += times > 1 ? 1 : 0;
    const auto f = clients[c]->failover();
    const bool ok = gaps.empty() && twice == 0 && t.mismatches == 0 && t.wrong_instance == 0 &&
                    t.instances.size() >= 2;
    failures += ok ? 0 : 1;
    std::printf(
        "%s client c%d: the walk's %zu pairs tiled by %zu answers (%lld of consecutive poses, "
        "%lld over more poses: latest-wins under load), %lld answered twice, %lld mismatches "
        "against sweptccd query, %lld contacts, %zu joins, %lld events from another instance "
        "delivered; fenced %lld events and %lld hellos, %lld doors of another room refused, "
        "%lld heartbeat losses, %lld poses "
        "re-sent, %lld repeated answers dropped, %lld resolve failures%s%s\n",
        ok ? "ok" : "FAIL", c, pairs, sorted.size(), static_cast<long long>(consecutive),
        static_cast<long long>(merged), static_cast<long long>(twice),
        static_cast<long long>(t.mismatches), static_cast<long long>(t.contacts),
        t.instances.size(), static_cast<long long>(t.wrong_instance),
        static_cast<long long>(f.fenced_events), static_cast<long long>(f.fenced_hellos),
        static_cast<long long>(f.wrong_rooms), static_cast<long long>(f.heartbeat_losses),
        static_cast<long long>(f.resent_poses), static_cast<long long>(f.repeated_answers),
        static_cast<long long>(f.resolve_failures),
        gaps.empty() ? "" : "; not tiled:", gaps.c_str());
  }
  std::fflush(stdout);
  for (auto& c : clients) c->Leave();
  return failures == 0 ? 0 : 1;
}
