#pragma once
// Signed messages: HMAC-SHA256 (RFC 2104) over the encoded LCM bytes of a
// message with its last 32 bytes (the `mac` field, last in every type the
// service receives or publishes) excluded, so a receiver verifies the raw
// datagram before decoding it. Unsigned mode writes an all-zero mac.
// The HMAC is computed with OpenSSL's SHA-256 (SHA-NI where the CPU has it;
// libsodium 1.0.18's is portable C, 5x slower on a 1.8 KB pose) from the
// key's inner and outer digest states, hashed once per key; keys, random
// bytes and sealed boxes stay libsodium's.

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace sweptccd {

inline constexpr size_t kMacBytes = 32;
inline constexpr size_t kKeyBytes = 32;

namespace internal {
/// The key's HMAC inner and outer SHA-256 states (OpenSSL digest contexts
/// after the padded key block), computed once; read-only afterwards, so one
/// is shared by every copy of the key and by every thread.
struct HmacPads;
}  // namespace internal

/// A 32-byte HMAC-SHA256 key. Its bytes are wiped when it is destroyed (and
/// its digest states when the last copy goes). Copies are cheap (the
/// digest states are shared). Throws std::runtime_error when OpenSSL cannot
/// set up SHA-256.
class MacKey {
 public:
  explicit MacKey(const std::array<uint8_t, kKeyBytes>& bytes);
  ~MacKey();
  MacKey(const MacKey&) = default;
  MacKey& operator=(const MacKey&) = default;
  const uint8_t* data() const { return bytes_.data(); }
  const internal::HmacPads& pads() const { return *pads_; }

 private:
  std::array<uint8_t, kKeyBytes> bytes_;
  std::shared_ptr<const internal::HmacPads> pads_;
};

/// Parses 64 hex digits (surrounding whitespace ignored). Throws InputError
/// naming `where` and the fix when the text is anything else.
MacKey ParseKeyHex(std::string_view text, const std::string& where);

/// Reads a key file: a regular file, not readable or writable by group or
/// others (mode & 077 == 0), holding one key as 64 hex digits. Throws
/// InputError with one line naming the file and the fix (e.g. chmod 600).
MacKey LoadKeyFile(const std::string& path);

/// Writes a new random key (libsodium randombytes) as 64 hex digits to
/// `path`, created with mode 600; refuses to overwrite an existing file.
/// Throws InputError.
void WriteNewKeyFile(const std::string& path);

/// Fills the last kMacBytes of `bytes` with the HMAC of the bytes before
/// them under `key`, or with zeros when `key` is null (unsigned mode).
/// Precondition: size >= kMacBytes. Thread-safe.
void SignEncoded(uint8_t* bytes, size_t size, const MacKey* key);

/// True when the last kMacBytes of `bytes` are the HMAC of the bytes before
/// them under `key` (constant-time compare). False when size < kMacBytes.
/// Thread-safe.
bool VerifyEncoded(const void* bytes, size_t size, const MacKey& key);

/// Encodes `msg` (an lcm-gen type whose last field is `byte mac[32]`) and
/// signs it with `key` (null: unsigned). Publish the result with
/// lcm::LCM::publish(channel, data, size). Throws std::runtime_error when
/// the message cannot be encoded.
template <class T>
std::vector<uint8_t> EncodeSigned(const T& msg, const MacKey* key) {
  const int size = msg.getEncodedSize();
  if (size < static_cast<int>(kMacBytes)) throw std::runtime_error("message too short to sign");
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  if (msg.encode(bytes.data(), 0, size) != size) throw std::runtime_error("cannot encode message");
  SignEncoded(bytes.data(), bytes.size(), key);
  return bytes;
}

/// A fresh random key (libsodium randombytes): a live session's key.
MacKey NewRandomKey();

/// An X25519 key pair (libsodium crypto_box) that a joining client makes for
/// one daemon instance: the daemon seals the session key to `public_key`.
/// The secret half is wiped when destroyed.
inline constexpr size_t kBoxPublicKeyBytes = 32;
inline constexpr size_t kSealedKeyBytes = 80;  // crypto_box_SEALBYTES + kKeyBytes.
struct BoxKeyPair {
  std::array<uint8_t, kBoxPublicKeyBytes> public_key{};
  std::array<uint8_t, 32> secret_key{};
  ~BoxKeyPair();
};
BoxKeyPair NewBoxKeyPair();

/// `key` sealed (crypto_box_seal: anonymous sender, only the holder of the
/// secret key opens it) to `public_key`: kSealedKeyBytes bytes.
std::vector<uint8_t> SealKey(const MacKey& key, const uint8_t* public_key);
/// The key sealed in `sealed` to `pair`, or nullopt when it does not open
/// (wrong size, another recipient, tampered).
std::optional<MacKey> OpenSealedKey(const uint8_t* sealed, size_t size, const BoxKeyPair& pair);

/// The keys of a room: per-client keys, a room key for clients without
/// their own, and the service key that signs what the service publishes
/// (default: the room key). Immutable once built; thread-safe to read.
class KeyRing {
 public:
  KeyRing() = default;
  void SetRoomKey(MacKey key) { room_.emplace(key); }
  void SetServiceKey(MacKey key) { service_.emplace(key); }
  /// Throws InputError when `client_id` breaks the id rule.
  void SetClientKey(const std::string& client_id, MacKey key);

  /// The client's own key, else the room key, else null.
  const MacKey* KeyFor(std::string_view client_id) const;
  /// The service key, else the room key, else null.
  const MacKey* ServiceKey() const;
  /// The room key (signs join requests), or null.
  const MacKey* RoomKey() const { return room_ ? &*room_ : nullptr; }

 private:
  std::optional<MacKey> room_;
  std::optional<MacKey> service_;
  std::map<std::string, MacKey, std::less<>> clients_;
};

}  // namespace sweptccd
