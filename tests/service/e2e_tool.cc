// Test helper for the end-to-end daemon tests (not a GoogleTest binary).
// Modes:
//
//   e2e_tool publish URL POSES.jsonl RATE_HZ ID...
//     Publishes pose k of POSES.jsonl (seq k, the file's utime) for every
//     client ID, one round every 1/RATE_HZ seconds, then exits.
//
//   e2e_tool lockstep URL ID POSES.jsonl EXPECTED.jsonl
//     Publishes ID's poses one at a time, waiting (bounded) for the event of
//     each pair before the next, so the daemon never has to skip; every event
//     must answer (k-1, k) and equal EXPECTED line k-1 (`sweptccd query`).
//
//   e2e_tool probe URL CHANNEL
//     Publishes a few bytes on CHANNEL once (to see that a logger listens).
//
//   e2e_tool crash URL CHANNEL TYPE
//     Publishes on CHANNEL the 36-byte datagram that crashed lcm-gen 1.3.1's
//     decoders: TYPE's fingerprint (pose, contact, status or reject), a
//     utime, and a first string length of INT32_MIN.
//
//   e2e_tool collect URL POSES.jsonl EXPECTED.jsonl SWEPTCCD SKELETON ENV
//                    READY_FILE TIMEOUT_S ID...
//     Subscribes to contact events, touches READY_FILE once subscribed, and
//     collects until every ID has an event ending at the last pose (or fails
//     after TIMEOUT_S). Checks per client: pair numbers 0, 1, ... without
//     gaps, the events chain the poses (seq0 = previous seq1, first seq0 0),
//     answered + skipped + seq_gaps (poses the daemon reports it never
//     received, from a status_t published after the last event) = the last
//     answered pose, poses lost after it are printed (a client is done at
//     the last pose, or 3 s after its events stop; with --skip-forged, events
//     lost before this subscriber read them are counted and the chain
//     resumes after them), and every
//     event equals `sweptccd query`: consecutive pairs against EXPECTED
//     line seq0, a skipped-over pair against `sweptccd query` run on the
//     two-line pose file (seq0, seq1).
//
//   e2e_tool badinput URL GOOD_ID BAD_ID POSES.jsonl EXPECTED.jsonl
//     Publishes GOOD_ID's stream lock-step (as lockstep) and, between its
//     poses, one bad message per step (BAD_ID and an unknown client, raw
//     garbage bytes); checks each bad message gets a rejection_t with the
//     right reason, client and seq, BAD_ID (one accepted pose) gets no event,
//     and every GOOD_ID event equals EXPECTED.
//
// Every mode takes `--key FILE` first (e2e_tool --key FILE MODE ...): poses
// are then signed with that key (a daemon in signed mode refuses others) and
// every message received from the daemon must verify with it (`--key FILE
// --skip-forged`: one that does not, or does not decode, is counted and
// dropped: the attack test forges on purpose); without it
// poses go unsigned and nothing is verified. badinput then also checks
// bad_signature. Received messages are decoded through DecodeChecked.
//
// Exit 0 when every check passes; every wait is bounded.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/errors.h"
#include "msgs/channels.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/tracker_pose.h"

namespace {

using sweptccd::kContactChannel;
using sweptccd::kPoseChannel;
using sweptccd::kRejectChannel;
using sweptccd::kStatusChannel;

std::optional<sweptccd::MacKey> g_key;  // --key: signs every pose, verifies every answer.
// --skip-forged (after --key): an undecodable or unverified message is counted
// and dropped instead of ending the run (the attack test forges on purpose).
bool g_skip_forged = false;
int64_t g_skipped_forged = 0;

// Publishes a pose signed with --key (unsigned without it).
void Send(lcm::LCM& lcm, const sweptccd::tracker_pose_t& m) {
  const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(m, g_key ? &*g_key : nullptr);
  lcm.publish(kPoseChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
}

// Decodes what the daemon publishes through DecodeChecked and, with --key,
// verifies each message's mac (a failure ends the run: exit 1).
struct Receiver {
  std::vector<sweptccd::contact_event_t> events;
  std::vector<sweptccd::rejection_t> rejections;
  std::optional<sweptccd::status_t> status;  // The newest.
  template <class T>
  static std::optional<T> Checked(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    sweptccd::DecodeResult<T> r = sweptccd::DecodeChecked<T>(rbuf->data, rbuf->data_size, {});
    const bool verified = !g_key || sweptccd::VerifyEncoded(rbuf->data, rbuf->data_size, *g_key);
    if (r.ok() && verified) return std::move(*r.message);
    if (g_skip_forged && g_key) {
      ++g_skipped_forged;
      return std::nullopt;
    }
    if (!r.ok()) {
      std::fprintf(stderr, "e2e_tool: undecodable message on %s: %s\n", channel.c_str(),
                   r.problem.c_str());
    } else {
      std::fprintf(stderr, "e2e_tool: a message on %s does not verify\n", channel.c_str());
    }
    std::exit(1);
  }
  void On(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    if (auto m = Checked<sweptccd::contact_event_t>(rbuf, channel)) events.push_back(std::move(*m));
  }
  void OnReject(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    if (auto m = Checked<sweptccd::rejection_t>(rbuf, channel)) rejections.push_back(std::move(*m));
  }
  void OnStatus(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    if (auto m = Checked<sweptccd::status_t>(rbuf, channel)) status = std::move(*m);
  }
};

std::vector<nlohmann::json> ReadLines(const std::string& path) {
  std::vector<nlohmann::json> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  }
  return out;
}

sweptccd::tracker_pose_t MakePose(const nlohmann::json& p, const std::string& id, int64_t seq) {
  sweptccd::tracker_pose_t m = sweptccd::TrackerPoseOfLine(p.dump());
  m.client_id = id;
  m.session = 1;
  m.seq = seq;
  return m;
}

int ResultCode(const nlohmann::json& want) {
  return want["result"] == "contact" ? 1 : want["result"] == "free" ? 0 : 2;
}

// Whether event e equals the `sweptccd query` record want (result, and for a
// contact s_lo/s_hi bit-equal and initially_colliding).
bool Same(const sweptccd::contact_event_t& e, const nlohmann::json& want) {
  const int want_result = ResultCode(want);
  if (e.result != want_result) return false;
  if (want_result != 1) return true;
  return e.s_lo == want["s_lo"].get<double>() && e.s_hi == want["s_hi"].get<double>() &&
         e.initially_colliding == want["initially_colliding"].get<bool>();
}

int Publish(int argc, char** argv) {
  if (argc < 6) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  const std::vector<nlohmann::json> poses = ReadLines(argv[3]);
  const double rate = std::atof(argv[4]);
  const auto period = std::chrono::duration<double>(1.0 / rate);
  auto next = std::chrono::steady_clock::now();
  for (size_t k = 0; k < poses.size(); ++k) {
    for (int c = 5; c < argc; ++c) {
      Send(lcm, MakePose(poses[k], argv[c], static_cast<int64_t>(k)));
    }
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    std::this_thread::sleep_until(next);
  }
  std::printf("e2e_tool publish: %zu poses x %d clients at %g Hz\n", poses.size(), argc - 5,
              rate);
  return 0;
}

int Lockstep(int argc, char** argv) {
  if (argc != 6) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  Receiver rx;
  lcm.subscribe(kContactChannel, &Receiver::On, &rx);
  const std::vector<nlohmann::json> poses = ReadLines(argv[4]);
  const std::vector<nlohmann::json> expected = ReadLines(argv[5]);
  int mismatches = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    Send(lcm, MakePose(poses[k], argv[3], static_cast<int64_t>(k)));
    if (k == 0) continue;  // The first pose only anchors the stream.
    for (int waited_ms = 0; rx.events.size() < k && waited_ms < 10000; waited_ms += 10) {
      lcm.handleTimeout(10);
    }
    if (rx.events.size() < k) {
      std::fprintf(stderr, "e2e_tool lockstep: no event for pair %zu within 10 s\n", k - 1);
      return 1;
    }
    const sweptccd::contact_event_t& e = rx.events[k - 1];
    const nlohmann::json& want = expected.at(k - 1);
    if (e.seq0 != static_cast<int64_t>(k - 1) || e.seq1 != static_cast<int64_t>(k) ||
        !Same(e, want)) {
      ++mismatches;
      std::fprintf(stderr, "e2e_tool lockstep: pair %zu differs: event result %d s [%.17g, %.17g], "
                   "query %s\n", k - 1, e.result, e.s_lo, e.s_hi, want.dump().c_str());
    }
  }
  int contacts = 0;
  for (const auto& e : rx.events) contacts += e.result == 1;
  std::printf("e2e_tool lockstep: %zu events, %d contact, %d mismatches\n", rx.events.size(),
              contacts, mismatches);
  return mismatches == 0 && rx.events.size() + 1 == poses.size() ? 0 : 1;
}

int Probe(int argc, char** argv) {
  if (argc != 4) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  const char bytes[] = "probe";
  return lcm.publish(argv[3], bytes, sizeof bytes) == 0 ? 0 : 1;
}

int Crash(int argc, char** argv) {
  if (argc != 5) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  const std::string type = argv[4];
  int64_t hash = 0;
  if (type == "pose") hash = sweptccd::tracker_pose_t::getHash();
  if (type == "contact") hash = sweptccd::contact_event_t::getHash();
  if (type == "status") hash = sweptccd::status_t::getHash();
  if (type == "reject") hash = sweptccd::rejection_t::getHash();
  if (hash == 0) return 2;
  std::vector<uint8_t> bytes(36, 0);
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(static_cast<uint64_t>(hash) >> (56 - 8 * i));
  bytes[16] = 0x80;  // int32 INT32_MIN, big-endian.
  return lcm.publish(argv[3], bytes.data(), 36) == 0 ? 0 : 1;
}

int Collect(int argc, char** argv) {
  if (argc < 11) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  const std::string poses_path = argv[3];
  const std::vector<nlohmann::json> poses = ReadLines(poses_path);
  const std::vector<nlohmann::json> expected = ReadLines(argv[4]);
  const std::string sweptccd = argv[5], skeleton = argv[6], env = argv[7];
  const double timeout_s = std::atof(argv[9]);
  std::vector<std::string> ids(argv + 10, argv + argc);
  const int64_t last = static_cast<int64_t>(poses.size()) - 1;
  Receiver rx;
  lcm.subscribe(kContactChannel, &Receiver::On, &rx);
  lcm.subscribe(kStatusChannel, &Receiver::OnStatus, &rx);
  { std::ofstream ready(argv[8]); ready << "ready\n"; }
  std::map<std::string, std::vector<sweptccd::contact_event_t>> by_id;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(timeout_s));
  size_t seen = 0;
  // A client is done at its event ending at the last pose, or (the last
  // poses lost on the way) once its events have stopped for kQuiet.
  constexpr auto kQuiet = std::chrono::seconds(3);
  auto last_event = std::chrono::steady_clock::now();
  auto done = [&] {
    const bool quiet = std::chrono::steady_clock::now() - last_event > kQuiet;
    for (const auto& id : ids) {
      const auto it = by_id.find(id);
      if (it == by_id.end() || it->second.empty()) return false;
      if (it->second.back().seq1 != last && !quiet) return false;
    }
    return true;
  };
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    lcm.handleTimeout(20);
    if (seen < rx.events.size()) last_event = std::chrono::steady_clock::now();
    for (; seen < rx.events.size(); ++seen) by_id[rx.events[seen].client_id].push_back(rx.events[seen]);
  }
  // seq_gaps (poses the daemon never received) from a status published after
  // the last event; bounded wait.
  int64_t newest_event_utime = 0;
  for (const auto& e : rx.events) newest_event_utime = std::max(newest_event_utime, e.utime);
  for (int waited_ms = 0; waited_ms < 10000 && (!rx.status || rx.status->utime <= newest_event_utime);
       waited_ms += 20) {
    lcm.handleTimeout(20);
  }
  auto status_of = [&](const std::string& id, const char* field) -> int64_t {
    if (!rx.status) return 0;
    for (int32_t i = 0; i < rx.status->num_clients; ++i) {
      if (rx.status->client_id[i] != id) continue;
      return std::string(field) == "seq_gaps" ? rx.status->seq_gaps[i] : rx.status->rate_limited[i];
    }
    return 0;
  };
  int failures = 0;
  if (!done()) {
    std::fprintf(stderr, "e2e_tool collect: not every client answered up to pose %lld within %g s\n",
                 static_cast<long long>(last), timeout_s);
    ++failures;
  }
  // `sweptccd query` on the two-line pose file (seq0, seq1): the reference
  // for a pair that latest-wins joined across skipped poses.
  auto query_pair = [&](int64_t s0, int64_t s1) {
    const std::string two = std::string(argv[8]) + ".pair.jsonl";
    const std::string out = std::string(argv[8]) + ".pair.out.jsonl";
    {
      std::ofstream f(two);
      f << poses.at(static_cast<size_t>(s0)).dump() << "\n"
        << poses.at(static_cast<size_t>(s1)).dump() << "\n";
    }
    const std::string cmd = "'" + sweptccd + "' query --skeleton '" + skeleton + "' --poses '" +
                            two + "' --env '" + env + "' --output '" + out + "'";
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "e2e_tool collect: failed: %s\n", cmd.c_str());
      std::exit(1);
    }
    return ReadLines(out).at(0);
  };
  // Self-check of that reference: on a consecutive pair it must give the
  // whole-file record bit for bit (so skipped-over pairs are judged fairly).
  for (int64_t s0 : {int64_t{0}, last - 1}) {
    const nlohmann::json a = query_pair(s0, s0 + 1), &b = expected.at(static_cast<size_t>(s0));
    for (const char* key : {"result", "s_lo", "s_hi", "initially_colliding"}) {
      if (a.contains(key) != b.contains(key) || (a.contains(key) && a[key] != b[key])) {
        std::fprintf(stderr, "e2e_tool collect: two-line query of pair %lld differs in %s\n",
                     static_cast<long long>(s0), key);
        ++failures;
      }
    }
  }
  std::map<std::pair<int64_t, int64_t>, nlohmann::json> skipped_cache;
  int compared = 0, nonconsecutive = 0;
  for (const auto& id : ids) {
    const auto& ev = by_id[id];
    int64_t prev_seq1 = 0, next_pair = 0, lost_in_transit = 0;
    for (size_t k = 0; k < ev.size(); ++k) {
      const auto& e = ev[k];
      // --skip-forged (a flooded bus): an event the daemon published may be
      // lost before this subscriber reads it; counted, the chain resumes.
      if (g_skip_forged && e.pair > next_pair && e.seq0 > prev_seq1) {
        lost_in_transit += e.pair - next_pair;
        next_pair = e.pair;
        prev_seq1 = e.seq0;
      }
      if (e.pair != next_pair++ || e.seq0 != prev_seq1 || e.seq1 <= e.seq0 ||
          e.seq1 > last) {
        std::fprintf(stderr, "e2e_tool collect: %s event %zu out of order: pair %lld seq %lld-%lld\n",
                     id.c_str(), k, static_cast<long long>(e.pair),
                     static_cast<long long>(e.seq0), static_cast<long long>(e.seq1));
        ++failures;
        break;
      }
      prev_seq1 = e.seq1;
      nlohmann::json want;
      if (e.seq1 == e.seq0 + 1) {
        want = expected.at(static_cast<size_t>(e.seq0));
      } else {
        ++nonconsecutive;
        auto key = std::make_pair(e.seq0, e.seq1);
        auto it = skipped_cache.find(key);
        if (it == skipped_cache.end()) it = skipped_cache.emplace(key, query_pair(e.seq0, e.seq1)).first;
        want = it->second;
      }
      ++compared;
      if (!Same(e, want)) {
        ++failures;
        std::fprintf(stderr, "e2e_tool collect: %s pair %lld-%lld differs: result %d s [%.17g, %.17g], "
                     "query %s\n", id.c_str(), static_cast<long long>(e.seq0),
                     static_cast<long long>(e.seq1), e.result, e.s_lo, e.s_hi, want.dump().c_str());
      }
    }
    const int64_t skipped = ev.empty() ? 0 : ev.back().skipped_pairs_total;
    const int64_t answered = ev.empty() ? 0 : ev.back().pair + 1;  // By the daemon.
    // UDP may lose poses before the daemon reads them: the daemon counts
    // those between received poses in status_t.seq_gaps; lost trailing poses
    // (after the last event) are counted apart and printed.
    const int64_t gaps = status_of(id, "seq_gaps");
    const int64_t final_seq1 = ev.empty() ? 0 : ev.back().seq1;
    const int64_t trailing = last - final_seq1;
    if (!rx.status || rx.status->utime <= newest_event_utime) {
      std::fprintf(stderr, "e2e_tool collect: no status_t after the last event within 10 s\n");
      ++failures;
    }
    if (answered + skipped + gaps != final_seq1) {
      std::fprintf(stderr,
                   "e2e_tool collect: %s: %lld answered + %lld skipped + %lld seq_gaps != %lld "
                   "(last answered pose)\n",
                   id.c_str(), static_cast<long long>(answered), static_cast<long long>(skipped),
                   static_cast<long long>(gaps), static_cast<long long>(final_seq1));
      ++failures;
    }
    std::printf("e2e_tool collect: %s: %lld answered (%zu events received, %lld lost in transit), "
                "%lld skipped, %lld seq_gaps, %lld lost at the end, %lld rate_limited (poses %lld)\n",
                id.c_str(), static_cast<long long>(answered), ev.size(),
                static_cast<long long>(lost_in_transit), static_cast<long long>(skipped),
                static_cast<long long>(gaps), static_cast<long long>(trailing),
                static_cast<long long>(status_of(id, "rate_limited")),
                static_cast<long long>(last + 1));
  }
  std::printf("e2e_tool collect: %d events compared (%d skipped-over pairs), %d failures, %lld "
              "forged or undecodable messages dropped\n",
              compared, nonconsecutive, failures, static_cast<long long>(g_skipped_forged));
  return failures == 0 ? 0 : 1;
}

int BadInput(int argc, char** argv) {
  if (argc != 7) return 2;
  lcm::LCM lcm(argv[2]);
  if (!lcm.good()) return 2;
  const std::string good = argv[3], bad = argv[4];
  const std::vector<nlohmann::json> poses = ReadLines(argv[5]);
  const std::vector<nlohmann::json> expected = ReadLines(argv[6]);
  Receiver rx;
  lcm.subscribe(kContactChannel, &Receiver::On, &rx);
  lcm.subscribe(kRejectChannel, &Receiver::OnReject, &rx);

  // The bad client's accepted anchor: seq 10, utime 5000000.
  struct Bad {
    std::string reason, client;
    int64_t seq;
    sweptccd::tracker_pose_t msg;
    std::vector<uint8_t> raw;  // Published as is when not empty.
    bool unsigned_msg = false;  // Published without a mac.
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto base = [&](int64_t seq, int64_t utime) {
    sweptccd::tracker_pose_t m = MakePose(poses[0], bad, seq);
    m.utime = utime;
    return m;
  };
  std::vector<Bad> cases;
  {
    sweptccd::tracker_pose_t m = base(11, 5100000);
    m.num_links -= 1;
    m.position.pop_back();
    m.orientation.pop_back();
    cases.push_back({"wrong_link_count", bad, 11, m, {}});
  }
  {
    sweptccd::tracker_pose_t m = base(12, 5200000);
    m.position[1][2] = nan;
    cases.push_back({"non_finite", bad, 12, m, {}});
  }
  {
    sweptccd::tracker_pose_t m = base(13, 5300000);
    m.orientation[2][0] = std::numeric_limits<double>::infinity();
    cases.push_back({"non_finite", bad, 13, m, {}});
  }
  {
    sweptccd::tracker_pose_t m = base(14, 5400000);
    m.orientation[0] = {0.0, 0.0, 0.0, 0.0};
    cases.push_back({"zero_quaternion", bad, 14, m, {}});
  }
  {
    sweptccd::tracker_pose_t m = base(15, 5500000);
    m.position[0][0] = 2e9;
    cases.push_back({"position_out_of_range", bad, 15, m, {}});
  }
  cases.push_back({"non_increasing_seq", bad, 10, base(10, 5600000), {}});  // duplicate seq
  cases.push_back({"non_increasing_utime", bad, 16, base(16, 4000000), {}});
  {
    sweptccd::tracker_pose_t m = MakePose(poses[0], "mallory", 0);
    cases.push_back({"unknown_client", "mallory", 0, m, {}});
  }
  {
    std::vector<uint8_t> garbage;
    uint32_t x = 12345;
    for (int i = 0; i < 97; ++i) {
      x = x * 1103515245u + 12345u;
      garbage.push_back(static_cast<uint8_t>(x >> 16));
    }
    cases.push_back({"decode_error", "", -1, {}, garbage});
  }
  {
    // A valid message cut short.
    sweptccd::tracker_pose_t m = base(17, 5700000);
    std::vector<uint8_t> buf(static_cast<size_t>(m.getEncodedSize()));
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    buf.resize(buf.size() / 2);
    cases.push_back({"decode_error", "", -1, {}, buf});
  }
  {
    // 36 bytes with a client_id length of INT32_MIN: crashed lcm-gen's decoder.
    std::vector<uint8_t> crash(36, 0);
    const uint64_t hash = static_cast<uint64_t>(sweptccd::tracker_pose_t::getHash());
    for (int i = 0; i < 8; ++i) crash[i] = static_cast<uint8_t>(hash >> (56 - 8 * i));
    crash[16] = 0x80;
    cases.push_back({"decode_error", "", -1, {}, crash});
  }
  {
    // A pose claiming 2^26 links in a few bytes: refused before allocating.
    sweptccd::tracker_pose_t m = base(17, 5700000);
    m.num_links = 0;
    m.position.clear();
    m.orientation.clear();
    std::vector<uint8_t> buf = sweptccd::EncodeSigned(m, g_key ? &*g_key : nullptr);
    const size_t at = 8 + 8 + 4 + bad.size() + 1 + 8 + 8;
    buf[at] = 0x04;
    cases.push_back({"decode_error", "", -1, {}, buf});
  }
  cases.push_back({"bad_client_id", "", -1, MakePose(poses[0], "x\n\x1b[31mforged", 0), {}});
  {
    sweptccd::tracker_pose_t m = base(18, 5800000);
    m.session = 0;
    cases.push_back({"stale_session", bad, 18, m, {}});
  }
  cases.push_back({"utime_jump", bad, 19, base(19, 5000000 + 20000000), {}});
  if (g_key) {
    Bad unsigned_pose{"bad_signature", bad, -1, base(20, 6000000), {}};
    unsigned_pose.unsigned_msg = true;
    cases.push_back(unsigned_pose);
  }

  int failures = 0;
  auto wait_for = [&](auto pred, const char* what) {
    for (int waited_ms = 0; !pred() && waited_ms < 10000; waited_ms += 10) lcm.handleTimeout(10);
    if (!pred()) {
      std::fprintf(stderr, "e2e_tool badinput: no %s within 10 s\n", what);
      return false;
    }
    return true;
  };
  // Anchor the bad client with one good pose.
  Send(lcm, base(10, 5000000));
  size_t next_case = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    Send(lcm, MakePose(poses[k], good, static_cast<int64_t>(k)));
    if (next_case < cases.size()) {
      Bad& c = cases[next_case];
      const size_t before = rx.rejections.size();
      if (!c.raw.empty()) {
        lcm.publish(kPoseChannel, c.raw.data(), static_cast<unsigned int>(c.raw.size()));
      } else if (c.unsigned_msg) {
        const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(c.msg, nullptr);
        lcm.publish(kPoseChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
      } else {
        Send(lcm, c.msg);
      }
      if (!wait_for([&] { return rx.rejections.size() > before; }, "rejection")) return 1;
      const sweptccd::rejection_t& r = rx.rejections[before];
      if (r.reason != c.reason || r.client_id != c.client || r.seq != c.seq) {
        ++failures;
        std::fprintf(stderr, "e2e_tool badinput: case %zu want %s (%s, %lld), got %s (%s, %lld): %s\n",
                     next_case, c.reason.c_str(), c.client.c_str(), static_cast<long long>(c.seq),
                     r.reason.c_str(), r.client_id.c_str(), static_cast<long long>(r.seq),
                     r.message.c_str());
      } else {
        std::printf("e2e_tool badinput: %s -> %s\n", c.reason.c_str(), r.message.c_str());
      }
      ++next_case;
    }
    if (k == 0) continue;
    if (!wait_for([&] {
          size_t n = 0;
          for (const auto& e : rx.events) n += e.client_id == good;
          return n >= k;
        }, "event")) return 1;
  }
  std::vector<sweptccd::contact_event_t> ev;
  for (const auto& e : rx.events) {
    if (e.client_id == good) {
      ev.push_back(e);
    } else {  // The bad client has one accepted pose only: no pair to answer.
      ++failures;
      std::fprintf(stderr, "e2e_tool badinput: event for unexpected client '%s'\n", e.client_id.c_str());
    }
  }
  for (size_t k = 0; k < ev.size(); ++k) {
    const auto& e = ev[k];
    if (e.seq0 != static_cast<int64_t>(k) || e.seq1 != static_cast<int64_t>(k + 1) ||
        e.pair != static_cast<int64_t>(k) || !Same(e, expected.at(k))) {
      ++failures;
      std::fprintf(stderr, "e2e_tool badinput: %s pair %zu differs\n", good.c_str(), k);
    }
  }
  if (next_case != cases.size() || ev.size() + 1 != poses.size() ||
      rx.rejections.size() != cases.size()) {
    ++failures;
    std::fprintf(stderr, "e2e_tool badinput: %zu/%zu cases, %zu rejections, %zu events\n", next_case,
                 cases.size(), rx.rejections.size(), ev.size());
  }
  std::printf("e2e_tool badinput: %zu cases, %zu good events, %d failures\n", cases.size(),
              ev.size(), failures);
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 2 && std::string(argv[1]) == "--key") {
    try {
      g_key.emplace(sweptccd::LoadKeyFile(argv[2]));
    } catch (const sweptccd::InputError& e) {
      std::fprintf(stderr, "e2e_tool: %s\n", e.what());
      return 2;
    }
    argv[2] = argv[0];
    argv += 2;
    argc -= 2;
    if (argc > 1 && std::string(argv[1]) == "--skip-forged") {
      g_skip_forged = true;
      argv[1] = argv[0];
      argv += 1;
      argc -= 1;
    }
  }
  const std::string mode = argc > 1 ? argv[1] : "";
  int rc = 2;
  if (mode == "publish") rc = Publish(argc, argv);
  if (mode == "lockstep") rc = Lockstep(argc, argv);
  if (mode == "probe") rc = Probe(argc, argv);
  if (mode == "crash") rc = Crash(argc, argv);
  if (mode == "collect") rc = Collect(argc, argv);
  if (mode == "badinput") rc = BadInput(argc, argv);
  if (rc == 2) std::fprintf(stderr, "e2e_tool: bad arguments (see the comment in e2e_tool.cc)\n");
  return rc;
}
