// A consumer of the installed SweptCCD package: signs a tracker_pose_t as a
// tracker does, checks it as the daemon does (mac, bounded decode), and
// sends it through LCM's in-process provider (memq://, no network).
// Prints "consumer: ok" and exits 0, or says what went wrong and exits 1.
#include <cstdio>
#include <string>

#include <lcm/lcm-cpp.hpp>

#include "core/errors.h"
#include "msgs/channels.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/live_client.h"

namespace {
int Fail(const char* what) {
  std::fprintf(stderr, "consumer: %s\n", what);
  return 1;
}

struct Receiver {
  int received = 0;
  const sweptccd::MacKey* key = nullptr;
  bool ok = false;
  void Handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    ++received;
    const auto decoded = sweptccd::DecodeChecked<sweptccd::tracker_pose_t>(
        rbuf->data, rbuf->data_size, sweptccd::WireLimits{});
    ok = channel == sweptccd::kPoseChannel && decoded.ok() &&
         sweptccd::VerifyEncoded(rbuf->data, rbuf->data_size, *key) &&
         decoded.message->num_links == 2 && decoded.message->position[1][2] == 1.75 &&
         sweptccd::PeekPoseClientId(rbuf->data, rbuf->data_size) == "alice";
  }
};
}  // namespace

int main() {
  const sweptccd::MacKey key = sweptccd::ParseKeyHex(
      "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f", "consumer key");
  try {  // InputError (core/errors.h) from the installed library.
    sweptccd::ParseKeyHex("not a key", "bad key");
    return Fail("a bad key was accepted");
  } catch (const sweptccd::InputError&) {
  }
  if (!sweptccd::IsValidClientId("alice")) return Fail("client id rule");

  sweptccd::tracker_pose_t pose{};
  pose.utime = 1000000;
  pose.client_id = "alice";
  pose.session = 1;
  pose.seq = 1;
  pose.num_links = 2;
  pose.position = {{0.0, 0.0, 1.0}, {0.0, 0.5, 1.75}};
  pose.orientation = {{1.0, 0.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}};
  const std::vector<uint8_t> bytes = sweptccd::EncodeSigned(pose, &key);
  if (!sweptccd::VerifyEncoded(bytes.data(), bytes.size(), key)) return Fail("mac does not verify");
  std::vector<uint8_t> forged = bytes;
  forged[20] ^= 1;
  if (sweptccd::VerifyEncoded(forged.data(), forged.size(), key)) return Fail("forgery verified");

  lcm::LCM lcm("memq://");
  if (!lcm.good()) return Fail("no LCM");
  Receiver receiver;
  receiver.key = &key;
  lcm.subscribe(sweptccd::kPoseChannel, &Receiver::Handle, &receiver);
  lcm.publish(sweptccd::kPoseChannel, bytes.data(), static_cast<unsigned>(bytes.size()));
  if (lcm.handleTimeout(1000) <= 0 || receiver.received != 1) return Fail("nothing received");
  if (!receiver.ok) return Fail("received pose does not decode, verify or match");
  // The client library: a configured client publishes a signed pose through
  // its own connection on memq:// (its callbacks and LCM thread start and
  // stop with it).
  sweptccd::LiveClient::Options options;
  options.lcm_url = "memq://";
  options.client_id = "alice";
  options.join = false;
  options.client_key = key;
  options.session = 7;
  sweptccd::LiveClient client(options);
  sweptccd::tracker_pose_t from_client = pose;
  if (!client.PublishPose(from_client)) return Fail("the client library did not publish");
  std::printf("consumer: ok (%zu signed bytes; client library linked)\n", bytes.size());
  return 0;
}
