#include "service/ws/proof.h"

#include <sodium.h>

#include <cstdint>
#include <vector>

namespace sweptccd::ws {

namespace {

constexpr char kHex[] = "0123456789abcdef";

std::string Hex(const uint8_t* bytes, size_t n) {
  std::string s(2 * n, '0');
  for (size_t i = 0; i < n; ++i) {
    s[2 * i] = kHex[bytes[i] >> 4];
    s[2 * i + 1] = kHex[bytes[i] & 15];
  }
  return s;
}

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// The proof message followed by kMacBytes bytes for the HMAC: the layout
// SignEncoded / VerifyEncoded (msgs/signing.h) work on.
std::vector<uint8_t> Signable(ProofKind kind, std::string_view challenge, std::string_view id) {
  const std::string message = ProofMessage(kind, challenge, id);
  std::vector<uint8_t> bytes(message.begin(), message.end());
  bytes.resize(bytes.size() + kMacBytes, 0);
  return bytes;
}

}  // namespace

std::string NewChallenge() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot start");
  uint8_t bytes[32];
  randombytes_buf(bytes, sizeof(bytes));
  return Hex(bytes, sizeof(bytes));
}

std::string ProofMessage(ProofKind kind, std::string_view challenge, std::string_view id) {
  std::string m;
  switch (kind) {
    case ProofKind::kJoin:
      m = "sweptccd-ws-v1 join";
      break;
    case ProofKind::kSubscribe:
      m = "sweptccd-ws-v1 subscribe";
      break;
    case ProofKind::kObject:
      m = "sweptccd-ws-v1 object";
      break;
  }
  m += '\n';
  m += challenge;
  if (kind != ProofKind::kSubscribe) {
    m += '\n';
    m += id;
  }
  return m;
}

std::string ComputeProof(const MacKey& key, ProofKind kind, std::string_view challenge,
                         std::string_view id) {
  std::vector<uint8_t> bytes = Signable(kind, challenge, id);
  SignEncoded(bytes.data(), bytes.size(), &key);
  return Hex(bytes.data() + bytes.size() - kMacBytes, kMacBytes);
}

bool VerifyProof(const MacKey& key, ProofKind kind, std::string_view challenge, std::string_view id,
                 std::string_view proof) {
  if (proof.size() != 2 * kMacBytes) return false;
  std::vector<uint8_t> bytes = Signable(kind, challenge, id);
  uint8_t* mac = bytes.data() + bytes.size() - kMacBytes;
  for (size_t i = 0; i < kMacBytes; ++i) {
    const int hi = HexDigit(proof[2 * i]), lo = HexDigit(proof[2 * i + 1]);
    if (hi < 0 || lo < 0) return false;
    mac[i] = static_cast<uint8_t>(hi << 4 | lo);
  }
  return VerifyEncoded(bytes.data(), bytes.size(), key);
}

}  // namespace sweptccd::ws
