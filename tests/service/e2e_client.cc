// Test helper for the end-to-end daemon test (not a GoogleTest binary):
// publishes a pose stream file as one client's tracker_pose_t messages, one
// at a time, waiting for the contact event of each pair (lock-step, so the
// daemon never has to skip), and compares every event with the record that
// `sweptccd query` wrote for the same pair. Exit 0 when all match.
//
//   e2e_client URL CLIENT_ID POSES.jsonl EXPECTED_RESULTS.jsonl

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace {

struct Receiver {
  std::vector<sweptccd::contact_event_t> events;
  void On(const lcm::ReceiveBuffer*, const std::string&, const sweptccd::contact_event_t* e) {
    events.push_back(*e);
  }
};

std::vector<nlohmann::json> ReadLines(const char* path) {
  std::vector<nlohmann::json> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: e2e_client URL CLIENT_ID POSES.jsonl EXPECTED.jsonl\n");
    return 2;
  }
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) {
    std::fprintf(stderr, "e2e_client: cannot open %s\n", argv[1]);
    return 2;
  }
  Receiver rx;
  lcm.subscribe("SWEPTCCD_CONTACT", &Receiver::On, &rx);
  const std::vector<nlohmann::json> poses = ReadLines(argv[3]);
  const std::vector<nlohmann::json> expected = ReadLines(argv[4]);
  int mismatches = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    sweptccd::tracker_pose_t m;
    m.utime = poses[k]["utime"].get<int64_t>();
    m.client_id = argv[2];
    m.seq = static_cast<int64_t>(k);
    m.num_links = static_cast<int32_t>(poses[k]["links"].size());
    for (const auto& l : poses[k]["links"]) {
      m.position.push_back({l[0].get<double>(), l[1].get<double>(), l[2].get<double>()});
      m.orientation.push_back(
          {l[3].get<double>(), l[4].get<double>(), l[5].get<double>(), l[6].get<double>()});
    }
    lcm.publish("SWEPTCCD_POSE", &m);
    if (k == 0) continue;  // The first pose only anchors the stream.
    // Wait (bounded) for this pair's event.
    for (int waited_ms = 0; rx.events.size() < k && waited_ms < 10000; waited_ms += 10) {
      lcm.handleTimeout(10);
    }
    if (rx.events.size() < k) {
      std::fprintf(stderr, "e2e_client: no event for pair %zu within 10 s\n", k - 1);
      return 1;
    }
    const sweptccd::contact_event_t& e = rx.events[k - 1];
    const nlohmann::json& want = expected.at(k - 1);
    const int want_result = want["result"] == "contact" ? 1 : want["result"] == "free" ? 0 : 2;
    bool same = e.seq0 == static_cast<int64_t>(k - 1) && e.seq1 == static_cast<int64_t>(k) &&
                e.result == want_result;
    if (same && want_result == 1) {
      same = e.s_lo == want["s_lo"].get<double>() && e.s_hi == want["s_hi"].get<double>() &&
             e.initially_colliding == want["initially_colliding"].get<bool>();
    }
    if (!same) {
      ++mismatches;
      std::fprintf(stderr, "e2e_client: pair %zu differs: event result %d s [%.17g, %.17g], "
                   "query %s\n", k - 1, e.result, e.s_lo, e.s_hi, want.dump().c_str());
    }
  }
  int contacts = 0;
  for (const auto& e : rx.events) contacts += e.result == 1;
  std::printf("e2e_client: %zu events, %d contact, %d mismatches\n", rx.events.size(), contacts,
              mismatches);
  return mismatches == 0 && rx.events.size() + 1 == poses.size() ? 0 : 1;
}
