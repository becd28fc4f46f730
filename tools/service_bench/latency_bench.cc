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
//   --phases burst|spread when the clients sample (default burst): burst, all
//                         clients at the start of each tick, one after
//                         another; spread, client c at c/CLIENTS of the
//                         period into each tick and its utime as much later,
//                         as headsets on independent clocks would be
//   --breakdown           also print to stderr where the environment part's
//                         time went (below)
//   --answers-out FILE    write every event's answer (client, seq0, seq1,
//                         result, flags, s_lo, s_hi), one line each
//
// Two threads, each with its own lcm::LCM on the same URL: the main thread
// publishes; a receive thread only takes each event's arrival time when its
// handler runs and stores it. The two meet after the run. With one thread,
// an event that arrived while the bench was still signing and publishing the
// rest of a 32-client tick waited for the next handleTimeout, so the bench's
// own publishing time was counted as the daemon's latency. A pose's sent time
// is taken just before lcm.publish, after it was signed (the client's cost).
//
// --breakdown splits the environment part's latency with the times the
// daemon puts in contact_event_t (system clock, the same machine's):
// publication -> daemon's handler (receive_utime), queue_us, compute_us, the
// rest until the event's utime (just before it is signed and published), and
// utime -> arrival at the bench's handler.
//
// A shared entry of A's pair (seq0, seq1) against client E is covered when
// the daemon has both A's pose seq1 and E's first sample with utime >= the
// pair's utime1 (> for a window of one instant; service/shared_world.cc,
// Covered). Its latency is taken from the later of those two publications
// to the entry's arrival; the line after the table also times each entry
// from A's pose alone (what an application waits after sending it) and
// gives the daemon's own queue_us of the entries. Entries
// ended_by_timeout are counted, not timed; entries missing for a pair that
// was answered and covered during the run are counted as dropped.

#include <algorithm>
#include <array>
#include <atomic>
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
#include <utility>
#include <vector>

#include "core/errors.h"
#include "core/percentile.h"
#include "msgs/channels.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/tracker_pose.h"

namespace {

using Clock = std::chrono::steady_clock;

double MicrosSince(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::micro>(to - from).count();
}

int64_t SystemUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// What the publisher recorded; written by the main thread only, read after
// the receive thread has been joined.
struct Sent {
  struct Pose {
    Clock::time_point at;
    int64_t at_utime = 0;  // System clock, for --breakdown.
  };
  std::map<std::pair<std::string, int64_t>, Pose> by_seq;                // (client, seq).
  std::map<std::string, std::map<int64_t, Clock::time_point>> by_utime;  // client: pose utime.
};

// One contact_event_t as it arrived (what the report needs of it).
struct EventArrival {
  Clock::time_point at;
  int64_t at_utime = 0;  // System clock, for --breakdown.
  std::string client_id;
  int64_t seq1 = 0;
  int64_t skipped_pairs_total = 0;
  int64_t receive_utime = 0, event_utime = 0;
  double queue_us = 0, compute_us = 0;
  // The answer itself, for --answers-out.
  int64_t seq0 = 0;
  int result = 0;
  bool initially_colliding = false, undecided = false;
  double s_lo = 0, s_hi = 0;
};

struct SharedArrival {
  Clock::time_point at;
  sweptccd::shared_contact_t msg;
};

// The receive thread: its own lcm::LCM; each handler takes the time first,
// then decodes and appends. Nothing it writes is read by another thread
// before Stop() has joined it, except last_arrival_ns (atomic, the drain's).
class Receiver {
 public:
  Receiver(const std::string& url, bool shared, size_t expected_events) : lcm_(url) {
    events_.reserve(expected_events);
    if (!lcm_.good()) return;
    lcm_.subscribe(sweptccd::kContactChannel, &Receiver::OnEvent, this)
        ->setQueueCapacity(sweptccd::kLcmQueueCapacity);
    if (shared) {
      lcm_.subscribe(sweptccd::kSharedContactChannel, &Receiver::OnShared, this)
          ->setQueueCapacity(sweptccd::kLcmQueueCapacity);
    }
  }

  bool good() { return lcm_.good(); }

  void Start() {
    thread_ = std::thread([this] {
      while (!stop_.load(std::memory_order_relaxed)) lcm_.handleTimeout(50);
    });
  }

  // Joins the thread; afterwards the arrivals may be read.
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

  // When the last message arrived (the drain's "nothing for 1 s").
  Clock::time_point last_arrival() const {
    return Clock::time_point(Clock::duration(last_arrival_ns_.load(std::memory_order_relaxed)));
  }

  const std::vector<EventArrival>& events() const { return events_; }
  const std::vector<SharedArrival>& shared() const { return shared_; }
  int64_t undecodable() const { return undecodable_; }

 private:
  void Heard(Clock::time_point now) {
    last_arrival_ns_.store(now.time_since_epoch().count(), std::memory_order_relaxed);
  }

  void OnEvent(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const Clock::time_point now = Clock::now();
    const int64_t now_utime = SystemUtime();
    Heard(now);
    sweptccd::contact_event_t e;
    if (e.decode(rbuf->data, 0, rbuf->data_size) < 0) {
      ++undecodable_;
      return;
    }
    events_.push_back({now, now_utime, std::move(e.client_id), e.seq1, e.skipped_pairs_total,
                       e.receive_utime, e.utime, e.queue_us, e.compute_us, e.seq0, e.result,
                       e.initially_colliding != 0, e.undecided != 0, e.s_lo, e.s_hi});
  }

  void OnShared(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const Clock::time_point now = Clock::now();
    Heard(now);
    SharedArrival a{now, {}};
    if (a.msg.decode(rbuf->data, 0, rbuf->data_size) < 0) {
      ++undecodable_;
      return;
    }
    shared_.push_back(std::move(a));
  }

  lcm::LCM lcm_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<Clock::rep> last_arrival_ns_{0};
  std::vector<EventArrival> events_;
  std::vector<SharedArrival> shared_;
  int64_t undecodable_ = 0;
};

// The matched results, computed after the run from Sent and the arrivals.
struct Collector {
  std::vector<double> latencies_us;
  std::set<std::pair<std::string, int64_t>> answered;  // (client, seq1) with an env part.
  int64_t skipped = 0;
  // --breakdown: publication -> daemon, queue, compute, rest, daemon -> bench.
  std::array<std::vector<double>, 5> parts_us;
  // Shared part.
  std::vector<double> shared_latencies_us;
  std::map<std::pair<std::string, int64_t>, int> shared_per_pair;  // (client, seq1): entries.
  std::set<std::pair<std::string, std::string>> contact_pairs;     // Unordered client pairs.
  std::vector<double> shared_compute_us;                           // shared_contact_t.compute_us.
  std::vector<double> shared_queue_us;                             // shared_entry_t.queue_us.
  std::vector<double> shared_from_pose_us;  // A's pose published -> the entry's arrival.
  int64_t shared_received = 0, shared_timeout = 0, shared_invalid = 0, shared_uncovered = 0;
  int64_t shared_messages = 0;  // shared_contact_t received (each carries entries).

  void On(const Sent& sent, const EventArrival& e) {
    const auto it = sent.by_seq.find({e.client_id, e.seq1});
    if (it == sent.by_seq.end()) return;
    latencies_us.push_back(MicrosSince(it->second.at, e.at));
    answered.insert({e.client_id, e.seq1});
    skipped = std::max(skipped, e.skipped_pairs_total);
    const double to_daemon = static_cast<double>(e.receive_utime - it->second.at_utime);
    const double in_daemon = static_cast<double>(e.event_utime - e.receive_utime);
    parts_us[0].push_back(to_daemon);
    parts_us[1].push_back(e.queue_us);
    parts_us[2].push_back(e.compute_us);
    parts_us[3].push_back(in_daemon - e.queue_us - e.compute_us);
    parts_us[4].push_back(static_cast<double>(e.at_utime - e.event_utime));
  }

  void OnShared(const Sent& sent, const SharedArrival& arrival) {
    const sweptccd::shared_contact_t* m = &arrival.msg;
    const auto a = sent.by_seq.find({m->client_id, m->seq1});
    if (a == sent.by_seq.end()) return;
    ++shared_messages;
    for (const sweptccd::shared_entry_t& e : m->entries) {
      const auto other = sent.by_utime.find(e.entity);
      if (other == sent.by_utime.end()) continue;
      ++shared_received;
      ++shared_per_pair[{m->client_id, m->seq1}];
      shared_compute_us.push_back(e.compute_us);
      shared_queue_us.push_back(e.queue_us);
      if (e.result == sweptccd::shared_entry_t::RESULT_INVALID) ++shared_invalid;
      if (e.result == sweptccd::shared_entry_t::RESULT_CONTACT) {
        contact_pairs.insert({std::min(m->client_id, e.entity), std::max(m->client_id, e.entity)});
      }
      if (e.ended_by_timeout) {
        ++shared_timeout;
        continue;
      }
      // Matched after the run, so a covering sample published after the
      // entry arrived is in the map too: that entry came before it.
      const auto cover = e.t_from < e.t_to ? other->second.lower_bound(m->utime1)
                                           : other->second.upper_bound(m->utime1);
      if (cover == other->second.end() || cover->second > arrival.at) {  // Cannot be.
        ++shared_uncovered;
        continue;
      }
      shared_latencies_us.push_back(MicrosSince(std::max(a->second.at, cover->second), arrival.at));
      shared_from_pose_us.push_back(MicrosSince(a->second.at, arrival.at));
    }
  }
};

using Stats = sweptccd::Summary;  // The one percentile rule (core/percentile.h).
using sweptccd::Summarise;

struct Options {
  bool room = false;
  double floor_y = 0, cx = 0, cz = 0;
  int grid_cols = 0;
  double spacing_m = 0;
  bool stagger = false;
  bool shared = false;
  std::string label;
  bool spread = false;  // --phases spread.
  bool breakdown = false;
  std::string answers_out;  // --answers-out: every event's answer, one line each.
};

// --answers-out FILE: "CLIENT SEQ0 SEQ1 RESULT INITIALLY UNDECIDED S_LO S_HI"
// per event (s exact, %.17g), so that two runs on different backends can be
// compared pair by pair where both answered the same pair
// (tools/service_bench/backends.sh). The client id is escaped for display.
bool WriteAnswers(const std::string& path, const std::vector<EventArrival>& events) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    std::fprintf(stderr, "latency_bench: cannot write '%s'\n",
                 sweptccd::EscapeForDisplay(path).c_str());
    return false;
  }
  for (const EventArrival& e : events) {
    std::fprintf(f, "%s %lld %lld %d %d %d %.17g %.17g\n",
                 sweptccd::EscapeForDisplay(e.client_id).c_str(), static_cast<long long>(e.seq0),
                 static_cast<long long>(e.seq1), e.result, e.initially_colliding ? 1 : 0,
                 e.undecided ? 1 : 0, e.s_lo, e.s_hi);
  }
  return std::fclose(f) == 0;
}

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
    } else if (a == "--phases" && left >= 1) {
      const std::string v = argv[++i];
      if (v != "burst" && v != "spread") {
        std::fprintf(stderr, "latency_bench: --phases '%s': use burst or spread\n", v.c_str());
        return false;
      }
      o->spread = v == "spread";
    } else if (a == "--breakdown") {
      o->breakdown = true;
    } else if (a == "--answers-out" && left >= 1) {
      o->answers_out = argv[++i];
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

// Publishes every client's poses on `lcm` for SECONDS at RATE_HZ (burst or
// spread, Options::spread) and records in `sent` when each went out.
// Returns the poses published.
int64_t PublishAll(lcm::LCM* lcm, const sweptccd::MacKey& key, const Options& options,
                   const std::vector<sweptccd::tracker_pose_t>& poses,
                   const std::vector<std::array<double, 2>>& offset, double rate, int ticks,
                   Sent* sent) {
  const int clients = static_cast<int>(offset.size());
  const auto period = std::chrono::duration<double>(1.0 / rate);
  const auto start = Clock::now();
  int64_t published = 0;
  for (int t = 0; t < ticks; ++t) {
    for (int c = 0; c < clients; ++c) {
      // Burst: every client at the tick's start, one after another. Spread:
      // client c at c / clients of the period, its utime as much later.
      const double phase = options.spread ? static_cast<double>(c) / clients : 0.0;
      std::this_thread::sleep_until(
          start + std::chrono::duration_cast<Clock::duration>(period * (t + phase)));
      // The clip loops; each client's utime advances at the publication rate.
      const size_t frame = options.stagger ? t + c * poses.size() / clients : t;
      sweptccd::tracker_pose_t m = poses[frame % poses.size()];
      for (auto& p : m.position) p[0] += offset[c][0], p[2] += offset[c][1];
      m.client_id = "client" + std::to_string(c);
      m.seq = t;
      m.utime = 1000000 + static_cast<int64_t>((t + phase) * 1e6 / rate);
      const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(m, &key);
      const Clock::time_point now = Clock::now();
      sent->by_seq[{m.client_id, m.seq}] = {now, SystemUtime()};
      sent->by_utime[m.client_id][m.utime] = now;
      lcm->publish(sweptccd::kPoseChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
      ++published;
    }
  }
  return published;
}

// Prints "--breakdown" (stderr): median and p99 of each part.
void PrintBreakdown(const Collector& collector) {
  static const char* const kNames[] = {"publication -> daemon's handler", "queue_us", "compute_us",
                                       "rest in the daemon", "daemon's utime -> bench's handler"};
  std::fprintf(stderr, "breakdown (median / p99 us):");
  for (size_t k = 0; k < collector.parts_us.size(); ++k) {
    const Stats s = Summarise(collector.parts_us[k]);
    std::fprintf(stderr, "%s %s %.1f / %.1f", k ? ";" : "", kNames[k], s.median, s.p99);
  }
  std::fprintf(stderr, "\n");
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (argc < 7 || !ParseOptions(argc, argv, &options)) {
    std::fprintf(stderr,
                 "usage: latency_bench URL POSES.jsonl CLIENTS RATE_HZ SECONDS KEY [--room FLOOR_Y "
                 "CX CZ] [--grid COLS SPACING_M] [--stagger] [--shared] [--label TEXT] "
                 "[--phases burst|spread] [--breakdown]\n");
    return 2;
  }
  std::optional<sweptccd::MacKey> key;  // Poses are signed, as in production.
  try {
    key.emplace(sweptccd::LoadKeyFile(argv[6]));
  } catch (const sweptccd::InputError& e) {
    std::fprintf(stderr, "latency_bench: %s\n", sweptccd::DisplayError(e.what()).c_str());
    return 2;
  }
  lcm::LCM lcm(argv[1]);  // The publisher's; the receive thread has its own.
  if (!lcm.good()) return 2;
  const int clients = std::stoi(argv[3]);
  const double rate = std::stod(argv[4]), seconds = std::stod(argv[5]);
  if (clients < 1 || !(rate > 0)) {
    std::fprintf(stderr, "latency_bench: CLIENTS '%s' and RATE_HZ '%s' must be positive\n", argv[3],
                 argv[4]);
    return 2;
  }
  std::vector<sweptccd::tracker_pose_t> poses;
  {
    std::ifstream in(argv[2]);
    std::string line;
    while (std::getline(in, line)) {
      sweptccd::tracker_pose_t m = sweptccd::TrackerPoseOfLine(line);
      m.session = 1;
      poses.push_back(m);
    }
  }
  if (poses.empty()) {
    std::fprintf(stderr, "latency_bench: no poses in '%s'\n", argv[2]);
    return 2;
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
  const int ticks = static_cast<int>(seconds * rate);
  Receiver receiver(argv[1], options.shared, static_cast<size_t>(clients) * ticks);
  if (!receiver.good()) return 2;
  receiver.Start();
  Sent sent;
  const int64_t published = PublishAll(&lcm, *key, options, poses, offset, rate, ticks, &sent);
  // Drain: 2 s; with --shared until nothing arrived for 1 s (at most 20 s),
  // so what is missing then was dropped, not late.
  const auto drain_start = Clock::now();
  while (true) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const auto now = Clock::now();
    if (!options.shared && now >= drain_start + std::chrono::seconds(2)) break;
    const auto last_heard = std::max(drain_start, receiver.last_arrival());
    if (options.shared && (now >= last_heard + std::chrono::seconds(1) ||
                           now >= drain_start + std::chrono::seconds(20))) {
      break;
    }
  }
  receiver.Stop();
  Collector collector;
  for (const EventArrival& e : receiver.events()) collector.On(sent, e);
  for (const SharedArrival& a : receiver.shared()) collector.OnShared(sent, a);
  if (receiver.undecodable() > 0) {
    std::fprintf(stderr, "latency_bench: %lld messages did not decode\n",
                 static_cast<long long>(receiver.undecodable()));
  }
  if (options.breakdown) PrintBreakdown(collector);
  if (!options.answers_out.empty() && !WriteAnswers(options.answers_out, receiver.events())) {
    return 2;
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
  const Stats queue = Summarise(collector.shared_queue_us);
  std::printf(
      "shared entries' queue_us (due -> query start, in the daemon): median %.1f, p99 %.1f, "
      "max %.1f\n",
      queue.median, queue.p99, queue.max);
  const Stats from_pose = Summarise(collector.shared_from_pose_us);
  std::printf(
      "shared entries from A's pose publication (covered entries): median %.1f, p99 %.1f, "
      "max %.1f us\n",
      from_pose.median, from_pose.p99, from_pose.max);
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
