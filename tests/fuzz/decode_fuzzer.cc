// Fuzzes the decoding of one LCM message type of msgs/ that crosses the wire
// (tracker_pose_t, contact_event_t, rejection_t, status_t), chosen at build
// time by SWEPTCCD_FUZZ_MSG: every byte string a datagram may carry, through
// the one entry point the daemon and the tools use, msgs/'s
// DecodeChecked<T>(data, size, WireLimits{}) (default limits), and through
// VerifyEncoded (the signature check the daemon runs on the raw datagram
// before decoding). A crash, a hang, an allocation over -malloc_limit_mb or
// -rss_limit_mb, or a broken property below (std::abort) is a finding.
//
// Properties, for every input:
//  - DecodeChecked sets exactly one of message and problem;
//  - an accepted message encodes again to exactly the input bytes (CheckWire
//    refuses trailing bytes, non-NUL-terminated strings and inner NULs, so
//    nothing the decoder drops can be in an accepted input);
//  - the re-encoded bytes, signed with a key, verify under that key and not
//    under another, and DecodeChecked accepts them again.

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "msgs/checked_decode.h"
#include "msgs/signing.h"

#define SWEPTCCD_STRINGIFY2(x) #x
#define SWEPTCCD_STRINGIFY(x) SWEPTCCD_STRINGIFY2(x)
#include SWEPTCCD_STRINGIFY(sweptccd/SWEPTCCD_FUZZ_MSG.hpp)

namespace {

using Msg = sweptccd::SWEPTCCD_FUZZ_MSG;

sweptccd::MacKey Key(uint8_t fill) {
  std::array<uint8_t, sweptccd::kKeyBytes> bytes;
  bytes.fill(fill);
  return sweptccd::MacKey(bytes);
}

void Check(bool condition) {
  if (!condition) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const sweptccd::MacKey key = Key(0x5a);
  static const sweptccd::MacKey other = Key(0xa5);
  // Any byte string, any size (shorter than a mac included): never crashes.
  const bool verified = sweptccd::VerifyEncoded(data, size, key);

  const sweptccd::DecodeResult<Msg> decoded =
      sweptccd::DecodeChecked<Msg>(data, size, sweptccd::WireLimits{});
  Check(decoded.ok() == decoded.problem.empty());
  if (!decoded.ok()) return 0;

  const int encoded_size = decoded.message->getEncodedSize();
  Check(encoded_size >= 0 && static_cast<size_t>(encoded_size) == size);
  std::vector<uint8_t> again(size);
  Check(decoded.message->encode(again.data(), 0, encoded_size) == encoded_size);
  Check(size == 0 || std::memcmp(again.data(), data, size) == 0);
  Check(sweptccd::VerifyEncoded(again.data(), again.size(), key) == verified);

  sweptccd::SignEncoded(again.data(), again.size(), &key);
  Check(sweptccd::VerifyEncoded(again.data(), again.size(), key));
  Check(!sweptccd::VerifyEncoded(again.data(), again.size(), other));
  Check(sweptccd::DecodeChecked<Msg>(again.data(), again.size(), sweptccd::WireLimits{}).ok());
  return 0;
}
