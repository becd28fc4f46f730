// Test helper for the hostile-network end-to-end test and benchmark (not a
// GoogleTest binary): plays one attack of the daemon's threat model
// (docs/SECURITY.md) and exits. Every loop is bounded in count and time.
//
//   attack_tool crash URL CHANNEL
//     A 36-byte tracker_pose_t whose client_id length is INT32_MIN (lcm-gen
//     1.3.1's decoder reads past the buffer on it), then the same bytes
//     framed as every other message type, on CHANNEL.
//   attack_tool unicast PORT CHANNEL
//     The crash bytes in an LCM datagram sent by unicast UDP to
//     127.0.0.1:PORT (a udpm socket is bound to 0.0.0.0).
//   attack_tool huge URL
//     A 60-byte pose claiming 2^26 links (pose channel), a status_t claiming
//     2^24 clients and a contact_event_t claiming 2^26 contacts (their
//     channels).
//   attack_tool forge URL ID
//     Unsigned forgeries: a pose as ID with seq = utime = INT64_MAX and a
//     session of INT64_MAX, a seq jump, a contact_event_t and a status_t as
//     if from the daemon.
//   attack_tool escape URL
//     A pose whose client_id holds a newline and ANSI escapes.
//   attack_tool flood URL ID KEY_FILE POSES.jsonl RATE_HZ SECONDS
//     A registered client (with its real key) flooding: ID's poses from the
//     file, re-numbered into one new session, at RATE_HZ for SECONDS.
//   attack_tool flood-unknown URL RATE_HZ SECONDS
//     Signed-looking poses of an unknown client id at RATE_HZ.
//   attack_tool flood-garbage URL SECONDS
//     Random bytes on the pose channel, unpaced, for SECONDS.
//
// Prints one line "attack_tool MODE: sent N" and exits 0 (2 on bad usage).

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "msgs/channels.h"
#include "msgs/signing.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/tracker_pose.h"

namespace {

using Clock = std::chrono::steady_clock;

void PutBig(std::vector<uint8_t>* out, uint64_t value, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out->push_back(static_cast<uint8_t>(value >> (8 * i)));
}

void PutString(std::vector<uint8_t>* out, const std::string& s) {
  PutBig(out, s.size() + 1, 4);
  out->insert(out->end(), s.begin(), s.end());
  out->push_back(0);
}

template <class T>
uint64_t Fingerprint() {
  return static_cast<uint64_t>(T::getHash());
}

// The 36 bytes that crash an unchecked lcm-gen decoder: fingerprint, utime,
// then a string length of INT32_MIN.
template <class T>
std::vector<uint8_t> CrashBytes() {
  std::vector<uint8_t> b;
  PutBig(&b, Fingerprint<T>(), 8);
  PutBig(&b, 1'000'000, 8);
  PutBig(&b, 0x80000000u, 4);
  b.resize(36, 0);
  return b;
}

int Crash(lcm::LCM* lcm, const std::string& channel) {
  const std::vector<std::vector<uint8_t>> all = {
      CrashBytes<sweptccd::tracker_pose_t>(), CrashBytes<sweptccd::contact_event_t>(),
      CrashBytes<sweptccd::status_t>()};
  for (const auto& bytes : all) lcm->publish(channel, bytes.data(), bytes.size());
  return static_cast<int>(all.size());
}

// An LCM "short message" datagram: magic LC02, sequence number, channel,
// NUL, payload (the udpm provider's framing).
int Unicast(int port, const std::string& channel) {
  std::vector<uint8_t> datagram;
  PutBig(&datagram, 0x4c433032, 4);
  PutBig(&datagram, 0, 4);
  datagram.insert(datagram.end(), channel.begin(), channel.end());
  datagram.push_back(0);
  const std::vector<uint8_t> payload = CrashBytes<sweptccd::tracker_pose_t>();
  datagram.insert(datagram.end(), payload.begin(), payload.end());
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return 0;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(port));
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  int sent = 0;
  for (int i = 0; i < 3; ++i) {
    sent += sendto(fd, datagram.data(), datagram.size(), 0, reinterpret_cast<sockaddr*>(&to),
                   sizeof to) == static_cast<ssize_t>(datagram.size());
  }
  close(fd);
  return sent;
}

int Huge(lcm::LCM* lcm) {
  std::vector<uint8_t> pose;
  PutBig(&pose, Fingerprint<sweptccd::tracker_pose_t>(), 8);
  PutBig(&pose, 1'000'000, 8);
  PutString(&pose, "alice");
  PutBig(&pose, 1, 8);        // session
  PutBig(&pose, 1, 8);        // seq
  PutBig(&pose, 1u << 26, 4);  // num_links
  pose.resize(60, 0);
  lcm->publish(sweptccd::kPoseChannel, pose.data(), pose.size());

  std::vector<uint8_t> status;
  PutBig(&status, Fingerprint<sweptccd::status_t>(), 8);
  PutBig(&status, 1'000'000, 8);
  PutString(&status, "cpu");
  PutString(&status, "");
  PutString(&status, "signed");
  PutBig(&status, 1u << 24, 4);  // num_clients
  status.resize(80, 0);
  lcm->publish(sweptccd::kStatusChannel, status.data(), status.size());

  sweptccd::contact_event_t event{};
  event.client_id = "alice";
  std::vector<uint8_t> contact(static_cast<size_t>(event.getEncodedSize()));
  event.encode(contact.data(), 0, static_cast<int>(contact.size()));
  // num_contacts sits after the fixed fields; rather than compute its offset
  // by hand, claim 2^26 contacts by patching the first zero int32 after the
  // doubles: any such field set huge must be refused before allocation.
  for (size_t off = 8; off + 4 <= contact.size(); off += 4) {
    std::vector<uint8_t> copy = contact;
    copy[off] = 0x04;  // 2^26 in the high byte of a big-endian int32.
    lcm->publish(sweptccd::kContactChannel, copy.data(), copy.size());
  }
  return 2 + static_cast<int>((contact.size() - 8) / 4);
}

sweptccd::tracker_pose_t PoseFromJson(const nlohmann::json& p, const std::string& id,
                                      int64_t session, int64_t seq, int64_t utime) {
  nlohmann::json line = {{"utime", utime}, {"links", p["links"]}};
  sweptccd::tracker_pose_t m = sweptccd::TrackerPoseOfLine(line.dump());
  m.client_id = id;
  m.session = session;
  m.seq = seq;
  return m;
}

sweptccd::tracker_pose_t OneLinkPose(const std::string& id, int64_t session, int64_t seq,
                                     int64_t utime) {
  nlohmann::json p = {{"links", {{0, 0, 1, 1, 0, 0, 0}}}};
  return PoseFromJson(p, id, session, seq, utime);
}

template <class T>
void PublishUnsigned(lcm::LCM* lcm, const std::string& channel, const T& msg) {
  const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(msg, nullptr);
  lcm->publish(channel, bytes.data(), bytes.size());
}

int Forge(lcm::LCM* lcm, const std::string& id) {
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  PublishUnsigned(lcm, sweptccd::kPoseChannel, OneLinkPose(id, kMax, kMax, kMax));
  PublishUnsigned(lcm, sweptccd::kPoseChannel, OneLinkPose(id, 0, 1'000'000'000, 2'000'000));
  sweptccd::contact_event_t event{};
  event.client_id = id;
  event.result = sweptccd::contact_event_t::RESULT_CONTACT;
  event.error = "";
  PublishUnsigned(lcm, sweptccd::kContactChannel, event);
  sweptccd::status_t status{};
  status.backend = "forged";
  status.security = "signed";
  PublishUnsigned(lcm, sweptccd::kStatusChannel, status);
  return 4;
}

int Escape(lcm::LCM* lcm) {
  const std::string id = "mallory\nCONTACT alice pair 0 \x1b[31mFORGED\x1b[0m";
  PublishUnsigned(lcm, sweptccd::kPoseChannel, OneLinkPose(id, 1, 0, 1'000'000));
  return 1;
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

// Calls send(k) at rate_hz (0: unpaced) until `seconds` have passed.
template <class Send>
int64_t Paced(double rate_hz, double seconds, Send send) {
  const auto start = Clock::now();
  const auto end = start + std::chrono::duration_cast<Clock::duration>(
                               std::chrono::duration<double>(seconds));
  int64_t k = 0;
  auto next = start;
  const auto period = rate_hz > 0 ? std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(1.0 / rate_hz))
                                  : Clock::duration::zero();
  while (Clock::now() < end) {
    send(k++);
    if (rate_hz > 0) {
      next += period;
      std::this_thread::sleep_until(next);
    }
  }
  return k;
}

int64_t Flood(lcm::LCM* lcm, const std::string& id, const std::string& key_file,
              const std::string& poses_path, double rate_hz, double seconds) {
  const sweptccd::MacKey key = sweptccd::LoadKeyFile(key_file);
  const std::vector<nlohmann::json> poses = ReadLines(poses_path);
  if (poses.empty()) return 0;
  const int64_t session = std::chrono::duration_cast<std::chrono::microseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count();
  const int64_t step_us = static_cast<int64_t>(1e6 / rate_hz);
  return Paced(rate_hz, seconds, [&](int64_t k) {
    const auto m = PoseFromJson(poses[static_cast<size_t>(k) % poses.size()], id, session, k,
                                1'000'000 + k * step_us);
    const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(m, &key);
    lcm->publish(sweptccd::kPoseChannel, bytes.data(), bytes.size());
  });
}

int64_t FloodUnknown(lcm::LCM* lcm, double rate_hz, double seconds) {
  return Paced(rate_hz, seconds, [&](int64_t k) {
    PublishUnsigned(lcm, sweptccd::kPoseChannel,
                    OneLinkPose("stranger" + std::to_string(k % 4096), 1, k, 1'000'000 + k));
  });
}

int64_t FloodGarbage(lcm::LCM* lcm, double seconds) {
  std::mt19937 rng(7);
  std::vector<uint8_t> bytes(64);
  return Paced(0, seconds, [&](int64_t k) {
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    lcm->publish(sweptccd::kPoseChannel, bytes.data(), 16 + static_cast<size_t>(k % 48));
  });
}

int Usage() {
  std::fprintf(stderr, "attack_tool: bad usage (see the comment at the top of attack_tool.cc)\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return Usage();
  const std::string mode = argv[1];
  try {
    if (mode == "unicast" && argc == 4) {
      std::printf("attack_tool unicast: sent %d\n", Unicast(std::atoi(argv[2]), argv[3]));
      return 0;
    }
    lcm::LCM lcm(argv[2]);
    if (!lcm.good()) return Usage();
    int64_t sent = -1;
    if (mode == "crash" && argc == 4) sent = Crash(&lcm, argv[3]);
    if (mode == "huge" && argc == 3) sent = Huge(&lcm);
    if (mode == "forge" && argc == 4) sent = Forge(&lcm, argv[3]);
    if (mode == "escape" && argc == 3) sent = Escape(&lcm);
    if (mode == "flood" && argc == 8) {
      sent = Flood(&lcm, argv[3], argv[4], argv[5], std::atof(argv[6]), std::atof(argv[7]));
    }
    if (mode == "flood-unknown" && argc == 5) {
      sent = FloodUnknown(&lcm, std::atof(argv[3]), std::atof(argv[4]));
    }
    if (mode == "flood-garbage" && argc == 4) sent = FloodGarbage(&lcm, std::atof(argv[3]));
    if (sent < 0) return Usage();
    std::printf("attack_tool %s: sent %lld\n", mode.c_str(), static_cast<long long>(sent));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "attack_tool %s: %s\n", mode.c_str(), e.what());
    return 1;
  }
}
