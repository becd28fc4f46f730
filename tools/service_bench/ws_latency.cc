// sweptccd_ws_latency: pose-to-event latency through the WebSocket door
// against the LCM door (tools/service_bench/ws_latency.sh runs it in a
// private network namespace). N live clients join through one door (each its
// own connection / LCM instance), stream the same walk at HZ for SECONDS,
// and every contact event's latency is taken from the moment its pose seq1
// was handed to the client library to the moment the event's callback ran.
//
//   sweptccd_ws_latency (ws [HOST:]PORT | lcm URL) SKELETON POSES.jsonl CLIENTS HZ SECONDS KEY
// (HOST: an IPv4 address of another network namespace, for
// tools/service_bench/fleet_latency.sh; default 127.0.0.1; "tls:HOST:PORT":
// wss:// without checking the certificate, a bench's self-signed one)
//
// Prints one table row: | door | clients | Hz | poses | events | p50 | p99 |
// max | intervals |. "intervals" is the pose intervals the events cover
// (seq1 - seq0 summed): a pair that latest-wins merged spans several, so with
// nothing lost or answered twice it is poses - clients whatever the load,
// while "events" falls short by the merges.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/percentile.h"
#include "sweptccd_client/live_client.h"
#include "sweptccd_client/ws_client.h"

namespace {

using namespace sweptccd;
using Clock = std::chrono::steady_clock;

struct Samples {
  std::mutex mutex;
  std::vector<std::vector<Clock::time_point>> sent;  // Per client, by seq.
  std::vector<double> latencies_us;
  int64_t events = 0;
  int64_t intervals = 0;
  void Event(int client, int64_t seq0, int64_t seq1) {
    const auto now = Clock::now();
    std::lock_guard<std::mutex> lock(mutex);
    ++events;
    intervals += seq1 - seq0;
    const auto& s = sent[static_cast<size_t>(client)];
    if (seq1 < 0 || seq1 >= static_cast<int64_t>(s.size())) return;
    latencies_us.push_back(std::chrono::duration<double, std::micro>(now - s[seq1]).count());
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 9) {
    std::fprintf(stderr,
                 "usage: sweptccd_ws_latency (ws PORT | lcm URL) SKELETON POSES CLIENTS HZ "
                 "SECONDS KEY\n");
    return 2;
  }
  const std::string door = argv[1], where = argv[2];
  const Skeleton skeleton = LoadSkeletonFile(argv[3]);
  const int n = std::stoi(argv[5]);
  const double hz = std::stod(argv[6]);
  const double seconds = std::stod(argv[7]);
  const MacKey key = LoadKeyFile(argv[8]);
  std::vector<tracker_pose_t> walk;
  {
    std::ifstream in(argv[4]);
    std::string line;
    while (std::getline(in, line)) {
      const auto j = nlohmann::json::parse(line);
      tracker_pose_t p{};
      p.utime = j["utime"].get<int64_t>();
      for (const auto& l : j["links"]) {
        p.position.push_back({l[0].get<double>(), l[1].get<double>(), l[2].get<double>()});
        p.orientation.push_back(
            {l[3].get<double>(), l[4].get<double>(), l[5].get<double>(), l[6].get<double>()});
      }
      p.num_links = static_cast<int32_t>(p.position.size());
      walk.push_back(std::move(p));
    }
  }
  const int total = std::min<int>(static_cast<int>(walk.size()), static_cast<int>(seconds * hz));
  Samples samples;
  samples.sent.assign(static_cast<size_t>(n), std::vector<Clock::time_point>(total));
  std::vector<std::unique_ptr<WsLiveClient>> ws;
  std::vector<std::unique_ptr<LiveClient>> lcm;
  for (int c = 0; c < n; ++c) {
    const std::string id = "bench" + std::to_string(c);
    JoinResult joined;
    if (door == "ws") {
      WsLiveClient::Options o;
      std::string at = where;
      if (at.rfind("tls:", 0) == 0) {  // wss://, the bench's self-signed certificate
        o.tls = true;
        o.verify_peer = false;
        at = at.substr(4);
      }
      const size_t colon = at.rfind(':');
      if (colon != std::string::npos) o.host = at.substr(0, colon);
      o.port =
          static_cast<uint16_t>(std::stoi(at.substr(colon == std::string::npos ? 0 : colon + 1)));
      o.client_id = id;
      o.room_key = key;
      o.skeleton = skeleton;
      o.reconnect = false;
      ws.push_back(std::make_unique<WsLiveClient>(o));
      ws.back()->OnContact([&samples, c](const contact_event_t& e) { samples.Event(c, e.seq0, e.seq1); });
      joined = ws.back()->Join();
    } else {
      LiveClient::Options o;
      o.lcm_url = where;
      o.client_id = id;
      o.room_key = key;
      o.skeleton = skeleton;
      o.rejoin = false;
      lcm.push_back(std::make_unique<LiveClient>(o));
      lcm.back()->OnContact([&samples, c](const contact_event_t& e) { samples.Event(c, e.seq0, e.seq1); });
      joined = lcm.back()->Join();
    }
    if (!joined.ok()) {
      std::fprintf(stderr, "join of %s failed: %s\n", id.c_str(), joined.message.c_str());
      return 1;
    }
  }
  const auto t0 = Clock::now() + std::chrono::milliseconds(100);
  const auto period = std::chrono::duration<double>(1.0 / hz);
  int64_t sent = 0;
  for (int i = 0; i < total; ++i) {
    std::this_thread::sleep_until(t0 + std::chrono::duration_cast<Clock::duration>(period * i));
    for (int c = 0; c < n; ++c) {
      tracker_pose_t p = walk[static_cast<size_t>(i)];
      p.seq = i;
      {
        std::lock_guard<std::mutex> lock(samples.mutex);
        samples.sent[static_cast<size_t>(c)][static_cast<size_t>(i)] = Clock::now();
      }
      const bool ok = door == "ws" ? ws[static_cast<size_t>(c)]->PublishPose(p)
                                   : lcm[static_cast<size_t>(c)]->PublishPose(p);
      sent += ok;
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  std::vector<double> lat;
  int64_t events = 0, intervals = 0;
  {
    std::lock_guard<std::mutex> lock(samples.mutex);
    lat = samples.latencies_us;
    events = samples.events;
    intervals = samples.intervals;
  }
  std::printf("| %s | %d | %.0f | %lld | %lld | %.0f | %.0f | %.0f | %lld |\n",
              door == "ws" ? "WebSocket" : "LCM", n, hz, static_cast<long long>(sent),
              static_cast<long long>(events), Percentile(lat, 0.5), Percentile(lat, 0.99),
              lat.empty() ? 0.0 : *std::max_element(lat.begin(), lat.end()),
              static_cast<long long>(intervals));
  for (auto& c : ws) c->Leave();
  for (auto& c : lcm) c->Leave();
  return 0;
}
