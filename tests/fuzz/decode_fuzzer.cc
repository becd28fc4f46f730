// Fuzzes the decoder of one LCM message type of msgs/, chosen at build time
// by SWEPTCCD_FUZZ_MSG (e.g. tracker_pose_t): every byte string a datagram
// may carry. The guard is the one the daemon applies on receipt
// (service/lcm_transport.cc): a negative status or a std::exception is a
// refusal; a crash, a hang or an allocation over -rss_limit_mb is a finding.
//
// A decoded message is encoded again and must decode to the same bytes.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <vector>

#define SWEPTCCD_STRINGIFY2(x) #x
#define SWEPTCCD_STRINGIFY(x) SWEPTCCD_STRINGIFY2(x)
#include SWEPTCCD_STRINGIFY(sweptccd/SWEPTCCD_FUZZ_MSG.hpp)

namespace {

using Msg = sweptccd::SWEPTCCD_FUZZ_MSG;

// The one place that decodes: after the msgs/ hardening this becomes the
// checked decoder (DecodeChecked<Msg>(data, size, limits)).
bool Decode(const uint8_t* data, size_t size, Msg* msg) {
  try {
    return msg->decode(data, 0, static_cast<int>(size)) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Msg msg;
  if (!Decode(data, size, &msg)) return 0;
  const int encoded_size = msg.getEncodedSize();
  if (encoded_size < 0) std::abort();
  std::vector<uint8_t> again(static_cast<size_t>(encoded_size));
  if (msg.encode(again.data(), 0, encoded_size) != encoded_size) std::abort();
  Msg round_trip;
  if (!Decode(again.data(), again.size(), &round_trip)) std::abort();
  return 0;
}
