// Service latency benchmark: N simulated clients publish tracker poses at a
// fixed rate over LCM; each contact event's arrival is matched with the
// publication of the pose it answers (seq1). Prints median, p99 and max
// latency (publication -> event arrival), the events received and the pairs
// the daemon skipped. Run through run.sh or shared_world.sh, which start the
// daemon inside a private network namespace.
//
//   latency_bench URL POSES.jsonl CLIENTS RATE_HZ SECONDS KEY [OPTIONS]
//
// Options (tools/service_bench/shared_world.sh; docs/BENCHMARKS.md "Shared
// world in the daemon"):
//   --room FLOOR_Y CX CZ  place the clip (y up) in a room: its root path's
//                         middle at (CX, CZ), its lowest link origin FLOOR_Y
//   --grid COLS SPACING_M client c stands (c % COLS, c / COLS) x SPACING_M
//                         along x and z from that place, the grid centred
//   --stagger             client c starts the clip c x frames/CLIENTS frames
//                         later (different poses in each tick)
//   --shared              also time shared_contact_t (SPEC 8): each entry of
//                         each message from the publication of its covering
//                         sample (below)
//   --label TEXT          the table row's label
//
// A shared entry of A's pair (seq0, seq1) against client E is covered when
// the daemon has both A's pose seq1 and E's first sample with utime > the
// pair's utime1 (service/shared_world.cc, Covered). Its latency is taken from
// the later of those two publications to the entry's arrival. Entries
// ended_by_timeout are counted, not timed; entries missing for a pair that
// was answered and covered during the run are counted as dropped.

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/errors.h"
#include "msgs/channels.h"
#include "msgs/signing.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double MicrosSince(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::micro>(to - from).count();
}

struct Collector {
  std::map<std::pair<std::string, int64_t>, Clock::time_point> sent;          // (client, seq).
  std::map<std::string, std::map<int64_t, Clock::time_point>> sent_by_utime;  // client: utime.
  std::vector<double> latencies_us;
  std::set<std::pair<std::string, int64_t>> answered;  // (client, seq1) with an env part.
  int64_t skipped = 0;
  // Shared part.
  std::vector<double> shared_latencies_us;
  std::map<std::pair<std::string, int64_t>, int> shared_per_pair;  // (client, seq1): entries.
  std::set<std::pair<std::string, std::string>> contact_pairs;     // Unordered client pairs.
  std::vector<double> shared_compute_us;                           // shared_contact_t.compute_us.
  int64_t shared_received = 0, shared_timeout = 0, shared_invalid = 0, shared_uncovered = 0;
  int64_t shared_messages = 0;  // shared_contact_t received (each carries entries).

  void On(const lcm::ReceiveBuffer*, const std::string&, const sweptccd::contact_event_t* e) {
    const Clock::time_point now = Clock::now();
    const auto it = sent.find({e->client_id, e->seq1});
    if (it == sent.end()) return;
    latencies_us.push_back(MicrosSince(it->second, now));
    answered.insert({e->client_id, e->seq1});
    skipped = std::max(skipped, e->skipped_pairs_total);
  }

  void OnShared(const lcm::ReceiveBuffer*, const std::string&,
                const sweptccd::shared_contact_t* m) {
    const Clock::time_point now = Clock::now();
    const auto a = sent.find({m->client_id, m->seq1});
    if (a == sent.end()) return;
    ++shared_messages;
    for (const sweptccd::shared_entry_t& e : m->entries) {
      const auto other = sent_by_utime.find(e.entity);
      if (other == sent_by_utime.end()) continue;
      ++shared_received;
      ++shared_per_pair[{m->client_id, m->seq1}];
      shared_compute_us.push_back(e.compute_us);
      if (e.result == sweptccd::shared_entry_t::RESULT_INVALID) ++shared_invalid;
      if (e.result == sweptccd::shared_entry_t::RESULT_CONTACT) {
        contact_pairs.insert({std::min(m->client_id, e.entity), std::max(m->client_id, e.entity)});
      }
      if (e.ended_by_timeout) {
        ++shared_timeout;
        continue;
      }
      const auto cover = other->second.upper_bound(m->utime1);
      if (cover == other->second.end()) {  // Answered before E's covering sample: cannot be.
        ++shared_uncovered;
        continue;
      }
      shared_latencies_us.push_back(MicrosSince(std::max(a->second, cover->second), now));
    }
  }
};

struct Stats {
  size_t n = 0;
  double median = 0, p99 = 0, max = 0;
};

Stats Summarise(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
  };
  return {v.size(), at(0.5), at(0.99), v.empty() ? 0.0 : v.back()};
}

struct Options {
  bool room = false;
  double floor_y = 0, cx = 0, cz = 0;
  int grid_cols = 0;
  double spacing_m = 0;
  bool stagger = false;
  bool shared = false;
  std::string label;
};

// Parses the options after the six positional arguments; false on a bad one.
bool ParseOptions(int argc, char** argv, Options* o) {
  for (int i = 7; i < argc; ++i) {
    const std::string a = argv[i];
    const int left = argc - i - 1;
    if (a == "--room" && left >= 3) {
      o->room = true;
      o->floor_y = std::stod(argv[++i]);
      o->cx = std::stod(argv[++i]);
      o->cz = std::stod(argv[++i]);
    } else if (a == "--grid" && left >= 2) {
      o->grid_cols = std::stoi(argv[++i]);
      o->spacing_m = std::stod(argv[++i]);
      if (o->grid_cols < 1) return false;
    } else if (a == "--stagger") {
      o->stagger = true;
    } else if (a == "--shared") {
      o->shared = true;
    } else if (a == "--label" && left >= 1) {
      o->label = argv[++i];
    } else {
      std::fprintf(stderr, "latency_bench: unknown or incomplete option '%s'\n", a.c_str());
      return false;
    }
  }
  return true;
}

// Moves every pose so the clip stands in the room (Options::room).
void PlaceInRoom(const Options& o, std::vector<sweptccd::tracker_pose_t>* poses) {
  double lowest = 1e300, x_lo = 1e300, x_hi = -1e300, z_lo = 1e300, z_hi = -1e300;
  for (const auto& m : *poses) {
    for (const auto& p : m.position) lowest = std::min(lowest, p[1]);
    x_lo = std::min(x_lo, m.position[0][0]), x_hi = std::max(x_hi, m.position[0][0]);
    z_lo = std::min(z_lo, m.position[0][2]), z_hi = std::max(z_hi, m.position[0][2]);
  }
  const double d[3] = {o.cx - 0.5 * (x_lo + x_hi), o.floor_y - lowest, o.cz - 0.5 * (z_lo + z_hi)};
  for (auto& m : *poses) {
    for (auto& p : m.position) {
      for (int k = 0; k < 3; ++k) p[k] += d[k];
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (argc < 7 || !ParseOptions(argc, argv, &options)) {
    std::fprintf(stderr,
                 "usage: latency_bench URL POSES.jsonl CLIENTS RATE_HZ SECONDS KEY [--room FLOOR_Y "
                 "CX CZ] [--grid COLS SPACING_M] [--stagger] [--shared] [--label TEXT]\n");
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
  if (options.room) PlaceInRoom(options, &poses);
  // Per-client offset (x, z) on the grid, centred on the room place.
  std::vector<std::array<double, 2>> offset(clients, {0.0, 0.0});
  if (options.grid_cols > 0) {
    const int rows = (clients + options.grid_cols - 1) / options.grid_cols;
    for (int c = 0; c < clients; ++c) {
      offset[c] = {(c % options.grid_cols - 0.5 * (options.grid_cols - 1)) * options.spacing_m,
                   (c / options.grid_cols - 0.5 * (rows - 1)) * options.spacing_m};
    }
  }
  Collector collector;
  lcm.subscribe(sweptccd::kContactChannel, &Collector::On, &collector)
      ->setQueueCapacity(sweptccd::kLcmQueueCapacity);
  if (options.shared) {
    lcm.subscribe(sweptccd::kSharedContactChannel, &Collector::OnShared, &collector)
        ->setQueueCapacity(sweptccd::kLcmQueueCapacity);
  }
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
      const size_t frame = options.stagger ? t + c * poses.size() / clients : t;
      sweptccd::tracker_pose_t m = poses[frame % poses.size()];
      for (auto& p : m.position) p[0] += offset[c][0], p[2] += offset[c][1];
      m.client_id = "client" + std::to_string(c);
      m.seq = t;
      m.utime = 1000000 + static_cast<int64_t>(t * 1e6 / rate);
      const Clock::time_point now = Clock::now();
      collector.sent[{m.client_id, m.seq}] = now;
      collector.sent_by_utime[m.client_id][m.utime] = now;
      const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(m, &*key);
      lcm.publish(sweptccd::kPoseChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
      ++published;
    }
  }
  // Drain: 2 s; with --shared until nothing arrived for 1 s (at most 20 s),
  // so what is missing then was dropped, not late.
  const auto drain_start = Clock::now();
  auto last_heard = drain_start;
  while (true) {
    const auto now = Clock::now();
    if (!options.shared && now >= drain_start + std::chrono::seconds(2)) break;
    if (options.shared && (now >= last_heard + std::chrono::seconds(1) ||
                           now >= drain_start + std::chrono::seconds(20))) {
      break;
    }
    if (lcm.handleTimeout(50) > 0) last_heard = Clock::now();
  }
  const Stats env = Summarise(collector.latencies_us);
  if (!options.shared) {
    std::printf("| %d | %.0f | %lld | %zu | %.1f | %.1f | %.1f |\n", clients, rate,
                static_cast<long long>(published), env.n, env.median, env.p99, env.max);
    return 0;
  }
  // The table rows of shared_world.sh (label, messages, median, p99, max).
  const std::string label = options.label.empty() ? "env part" : options.label;
  std::printf("| %s | %zu | %.1f | %.1f | %.1f |\n", label.c_str(), env.n, env.median, env.p99,
              env.max);
  if (collector.shared_received == 0 && collector.shared_per_pair.empty()) {
    std::printf("shared: none\n");
    return 0;
  }
  const Stats shared = Summarise(collector.shared_latencies_us);
  std::printf("| shared part | %zu | %.1f | %.1f | %.1f |\n", shared.n, shared.median, shared.p99,
              shared.max);
  // Dropped: answered pairs covered during the run (seq1 before the last
  // tick, so every other client published a later sample) whose entries
  // did not all arrive.
  int64_t expected = 0, missing = 0;
  for (const auto& [client, seq1] : collector.answered) {
    if (seq1 >= ticks - 1) continue;
    expected += clients - 1;
    const auto it = collector.shared_per_pair.find({client, seq1});
    missing += (clients - 1) - (it == collector.shared_per_pair.end() ? 0 : it->second);
  }
  const Stats compute = Summarise(collector.shared_compute_us);
  double compute_sum_us = 0;
  for (double v : collector.shared_compute_us) compute_sum_us += v;
  std::printf(
      "shared entries' compute_us (AnswerSharedJob in the daemon, wall time): median %.1f, "
      "mean %.1f, p99 %.1f, max %.1f\n",
      compute.median, compute.n ? compute_sum_us / compute.n : 0.0, compute.p99, compute.max);
  std::printf("shared messages: %lld received carrying %lld entries (%.2f entries a message)\n",
              static_cast<long long>(collector.shared_messages),
              static_cast<long long>(collector.shared_received),
              collector.shared_messages
                  ? static_cast<double>(collector.shared_received) / collector.shared_messages
                  : 0.0);
  const int64_t client_pairs = static_cast<int64_t>(clients) * (clients - 1) / 2;
  std::printf(
      "shared entries: %lld received, %lld expected for the covered answered pairs, %lld dropped, "
      "%lld ended_by_timeout, %lld invalid, %lld before their covering sample; client pairs with "
      "a shared contact: %zu of %lld (%.1f%%); pairs skipped by latest-wins: %lld\n",
      static_cast<long long>(collector.shared_received), static_cast<long long>(expected),
      static_cast<long long>(missing), static_cast<long long>(collector.shared_timeout),
      static_cast<long long>(collector.shared_invalid),
      static_cast<long long>(collector.shared_uncovered), collector.contact_pairs.size(),
      static_cast<long long>(client_pairs),
      client_pairs ? 100.0 * collector.contact_pairs.size() / client_pairs : 0.0,
      static_cast<long long>(collector.skipped));
  return 0;
}
