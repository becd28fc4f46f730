// Service latency benchmark: N simulated clients publish tracker poses at a
// fixed rate over LCM; each contact event's arrival is matched with the
// publication of the pose it answers (seq1). Prints median, p99 and max
// latency (publication -> event arrival), the events received and the pairs
// the daemon skipped. Run through run.sh, which starts the daemon inside a
// private network namespace.
//
//   latency_bench URL POSES.jsonl CLIENTS RATE_HZ SECONDS

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/errors.h"
#include "msgs/channels.h"
#include "msgs/signing.h"

#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace {

using Clock = std::chrono::steady_clock;

struct Collector {
  std::map<std::pair<std::string, int64_t>, Clock::time_point> sent;
  std::vector<double> latencies_us;
  int64_t skipped = 0;
  void On(const lcm::ReceiveBuffer*, const std::string&, const sweptccd::contact_event_t* e) {
    const auto it = sent.find({e->client_id, e->seq1});
    if (it == sent.end()) return;
    latencies_us.push_back(
        std::chrono::duration<double, std::micro>(Clock::now() - it->second).count());
    skipped = std::max(skipped, e->skipped_pairs_total);
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) {
    std::fprintf(stderr, "usage: latency_bench URL POSES.jsonl CLIENTS RATE_HZ SECONDS KEY\n");
    return 2;
  }
  std::optional<sweptccd::MacKey> key;  // Poses are signed, as in production.
  try {
    key.emplace(sweptccd::LoadKeyFile(argv[6]));
  } catch (const sweptccd::InputError& e) {
    std::fprintf(stderr, "latency_bench: %s\n", e.what());
    return 2;
  }
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) return 2;
  const int clients = std::stoi(argv[3]);
  const double rate = std::stod(argv[4]), seconds = std::stod(argv[5]);
  std::vector<sweptccd::tracker_pose_t> poses;
  {
    std::ifstream in(argv[2]);
    std::string line;
    while (std::getline(in, line)) {
      const auto j = nlohmann::json::parse(line);
      sweptccd::tracker_pose_t m;
      m.session = 1;
      m.num_links = static_cast<int32_t>(j["links"].size());
      for (const auto& l : j["links"]) {
        m.position.push_back({l[0].get<double>(), l[1].get<double>(), l[2].get<double>()});
        m.orientation.push_back(
            {l[3].get<double>(), l[4].get<double>(), l[5].get<double>(), l[6].get<double>()});
      }
      poses.push_back(m);
    }
  }
  Collector collector;
  lcm.subscribe(sweptccd::kContactChannel, &Collector::On, &collector);
  const auto period = std::chrono::duration<double>(1.0 / rate);
  const int ticks = static_cast<int>(seconds * rate);
  const auto start = Clock::now();
  int64_t published = 0;
  for (int t = 0; t < ticks; ++t) {
    const auto due = start + std::chrono::duration_cast<Clock::duration>(period * t);
    while (Clock::now() < due) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(due - Clock::now());
      lcm.handleTimeout(std::max<int>(0, static_cast<int>(left.count())));
    }
    // Clients publish one after another within the tick; the clip loops and
    // each client's utime advances at the publication rate.
    for (int c = 0; c < clients; ++c) {
      sweptccd::tracker_pose_t m = poses[t % poses.size()];
      m.client_id = "client" + std::to_string(c);
      m.seq = t;
      m.utime = 1000000 + static_cast<int64_t>(t * 1e6 / rate);
      collector.sent[{m.client_id, m.seq}] = Clock::now();
      const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(m, &*key);
      lcm.publish(sweptccd::kPoseChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
      ++published;
    }
  }
  const auto drain_until = Clock::now() + std::chrono::seconds(2);
  while (Clock::now() < drain_until) lcm.handleTimeout(50);
  std::vector<double>& v = collector.latencies_us;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) { return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))]; };
  std::printf("| %d | %.0f | %lld | %zu | %.1f | %.1f | %.1f |\n", clients, rate,
              static_cast<long long>(published), v.size(), at(0.5), at(0.99),
              v.empty() ? 0.0 : v.back());
  return 0;
}
