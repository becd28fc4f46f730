#pragma once
// The WebSocket door's proofs (docs/WEBSOCKET.md section 4):
// hex(HMAC-SHA256(key, LABEL "\n" challenge ["\n" id])) with the keys the
// LCM door uses (msgs/signing.h), over a per-connection random challenge.

#include <string>
#include <string_view>

#include "msgs/signing.h"

namespace sweptccd::ws {

enum class ProofKind { kJoin, kSubscribe, kObject };

/// 64 lower-case hex digits of 32 fresh random bytes (libsodium).
std::string NewChallenge();

/// The message a proof signs: LABEL "\n" challenge, then "\n" id for joins
/// and objects.
std::string ProofMessage(ProofKind kind, std::string_view challenge, std::string_view id);

/// The proof, 64 lower-case hex digits.
std::string ComputeProof(const MacKey& key, ProofKind kind, std::string_view challenge,
                         std::string_view id);

/// Whether `proof` (64 hex digits, either case) is the proof under `key`;
/// compared in constant time. Thread-safe.
bool VerifyProof(const MacKey& key, ProofKind kind, std::string_view challenge, std::string_view id,
                 std::string_view proof);

}  // namespace sweptccd::ws
