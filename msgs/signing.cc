#include "msgs/signing.h"

#include <fcntl.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "core/errors.h"
#include "msgs/text.h"

namespace sweptccd {

namespace internal {

struct HmacPads {
  EVP_MD_CTX* inner = nullptr;  // SHA-256 after the block key ^ 0x36.
  EVP_MD_CTX* outer = nullptr;  // SHA-256 after the block key ^ 0x5c.
  HmacPads() = default;
  HmacPads(const HmacPads&) = delete;
  HmacPads& operator=(const HmacPads&) = delete;
  // EVP_MD_CTX_free wipes the digest state (OpenSSL's clear_free).
  ~HmacPads() {
    EVP_MD_CTX_free(inner);
    EVP_MD_CTX_free(outer);
  }
};

}  // namespace internal

namespace {

constexpr size_t kShaBlockBytes = 64;
constexpr size_t kShaBytes = 32;

// A SHA-256 context that has hashed one 64-byte block.
EVP_MD_CTX* DigestAfterBlock(const uint8_t* block) {
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  if (ctx == nullptr || EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr) != 1 ||
      EVP_DigestUpdate(ctx, block, kShaBlockBytes) != 1) {
    EVP_MD_CTX_free(ctx);
    throw std::runtime_error("OpenSSL cannot set up SHA-256 for HMAC");
  }
  return ctx;
}

// RFC 2104 with a 32-byte key: the key zero-padded to the 64-byte block.
std::shared_ptr<const internal::HmacPads> MakePads(const std::array<uint8_t, kKeyBytes>& key) {
  auto pads = std::make_shared<internal::HmacPads>();
  uint8_t block[kShaBlockBytes];
  for (size_t i = 0; i < kShaBlockBytes; ++i) block[i] = (i < kKeyBytes ? key[i] : 0) ^ 0x36;
  pads->inner = DigestAfterBlock(block);
  for (size_t i = 0; i < kShaBlockBytes; ++i) block[i] = (i < kKeyBytes ? key[i] : 0) ^ 0x5c;
  pads->outer = DigestAfterBlock(block);
  OPENSSL_cleanse(block, sizeof(block));
  return pads;
}

// One scratch context per thread: the pads are copied into it, never written.
EVP_MD_CTX* ScratchContext() {
  thread_local const std::unique_ptr<EVP_MD_CTX, void (*)(EVP_MD_CTX*)> ctx(EVP_MD_CTX_new(),
                                                                           &EVP_MD_CTX_free);
  return ctx.get();
}

// HMAC-SHA256 of bytes[0, size) into mac[0, 32); false when OpenSSL fails.
bool Hmac(const internal::HmacPads& pads, const uint8_t* bytes, size_t size, uint8_t* mac) {
  EVP_MD_CTX* ctx = ScratchContext();
  uint8_t inner[kShaBytes];
  unsigned int n = 0;
  const bool ok = ctx != nullptr && EVP_MD_CTX_copy_ex(ctx, pads.inner) == 1 &&
                  EVP_DigestUpdate(ctx, bytes, size) == 1 &&
                  EVP_DigestFinal_ex(ctx, inner, &n) == 1 && n == kShaBytes &&
                  EVP_MD_CTX_copy_ex(ctx, pads.outer) == 1 &&
                  EVP_DigestUpdate(ctx, inner, kShaBytes) == 1 &&
                  EVP_DigestFinal_ex(ctx, mac, &n) == 1 && n == kShaBytes;
  OPENSSL_cleanse(inner, sizeof(inner));
  return ok;
}

void InitSodium() {
  // sodium_init is thread-safe and idempotent; a failure leaves no usable RNG.
  static const int status = sodium_init();
  if (status < 0) throw std::runtime_error("libsodium failed to initialise");
}

std::string Errno() { return std::strerror(errno); }

std::string ReadSmallFile(int fd, const std::string& path) {
  std::string text;
  char buf[256];
  for (;;) {
    const ssize_t n = read(fd, buf, sizeof(buf));
    if (n < 0) throw InputError(path + ": cannot read the key file (" + Errno() + ")");
    if (n == 0) return text;
    text.append(buf, static_cast<size_t>(n));
    if (text.size() > 1024) {
      throw InputError(path + ": key file is over 1 KiB; it must hold one key as 64 hex digits "
                              "(make one with `sweptccd keygen --out FILE`)");
    }
  }
}

}  // namespace

MacKey::MacKey(const std::array<uint8_t, kKeyBytes>& bytes)
    : bytes_(bytes), pads_(MakePads(bytes)) {}

MacKey::~MacKey() { sodium_memzero(bytes_.data(), bytes_.size()); }

MacKey ParseKeyHex(std::string_view text, const std::string& where) {
  const auto is_space = [](char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  const std::string fix = "; write one key as 64 hex digits (make one with `sweptccd keygen --out FILE`)";
  if (text.size() != 2 * kKeyBytes) {
    throw InputError(where + ": the key is " + std::to_string(text.size()) +
                     " characters long, not 64" + fix);
  }
  InitSodium();
  std::array<uint8_t, kKeyBytes> bytes{};
  size_t length = 0;
  const char* end = nullptr;
  if (sodium_hex2bin(bytes.data(), bytes.size(), text.data(), text.size(), nullptr, &length,
                     &end) != 0 ||
      length != kKeyBytes || end != text.data() + text.size()) {
    sodium_memzero(bytes.data(), bytes.size());
    throw InputError(where + ": the key holds characters other than hex digits" + fix);
  }
  MacKey key(bytes);
  sodium_memzero(bytes.data(), bytes.size());
  return key;
}

MacKey LoadKeyFile(const std::string& path) {
  // O_NONBLOCK: a FIFO in place of the key must not block the open; it is
  // then refused as not a regular file. A symlink is followed: its target's
  // type and mode are what fstat checks.
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(path + ": cannot open the key file (" + Errno() + ")");
  struct stat st {};
  std::string text;
  try {
    if (fstat(fd, &st) != 0) throw InputError(path + ": cannot stat the key file (" + Errno() + ")");
    if (!S_ISREG(st.st_mode)) throw InputError(path + ": the key file is not a regular file");
    if ((st.st_mode & 077) != 0) {
      char mode[8];
      std::snprintf(mode, sizeof(mode), "%03o", static_cast<unsigned>(st.st_mode & 0777));
      throw InputError(path + ": the key file has mode " + mode +
                       ", readable or writable by others; run `chmod 600 " + path + "`");
    }
    text = ReadSmallFile(fd, path);
  } catch (...) {
    close(fd);
    throw;
  }
  close(fd);
  MacKey key = ParseKeyHex(text, path);
  sodium_memzero(text.data(), text.size());
  return key;
}

void WriteNewKeyFile(const std::string& path) {
  InitSodium();
  std::array<uint8_t, kKeyBytes> bytes{};
  randombytes_buf(bytes.data(), bytes.size());
  char hex[2 * kKeyBytes + 1];
  sodium_bin2hex(hex, sizeof(hex), bytes.data(), bytes.size());
  sodium_memzero(bytes.data(), bytes.size());
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd < 0) {
    sodium_memzero(hex, sizeof(hex));
    throw InputError(path + ": cannot create the key file (" + Errno() +
                     "); give a new path (an existing file is never overwritten)");
  }
  std::string line = std::string(hex, 2 * kKeyBytes) + "\n";
  sodium_memzero(hex, sizeof(hex));
  const bool ok = fchmod(fd, 0600) == 0 &&
                  write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  sodium_memzero(line.data(), line.size());
  const bool closed = close(fd) == 0;
  if (!ok || !closed) throw InputError(path + ": cannot write the key file (" + Errno() + ")");
}

void SignEncoded(uint8_t* bytes, size_t size, const MacKey* key) {
  if (size < kMacBytes) throw std::runtime_error("message too short to sign");
  uint8_t* mac = bytes + size - kMacBytes;
  if (key == nullptr) {
    std::memset(mac, 0, kMacBytes);
    return;
  }
  if (!Hmac(key->pads(), bytes, size - kMacBytes, mac)) {
    throw std::runtime_error("HMAC-SHA256 failed (OpenSSL)");
  }
}

bool VerifyEncoded(const void* bytes, size_t size, const MacKey& key) {
  if (size < kMacBytes) return false;
  const auto* b = static_cast<const uint8_t*>(bytes);
  uint8_t expected[kMacBytes];
  // A mac that cannot be computed verifies nothing.
  const bool ok = Hmac(key.pads(), b, size - kMacBytes, expected) &&
                  CRYPTO_memcmp(expected, b + size - kMacBytes, kMacBytes) == 0;
  OPENSSL_cleanse(expected, sizeof(expected));
  return ok;
}

void KeyRing::SetClientKey(const std::string& client_id, MacKey key) {
  if (!IsValidClientId(client_id)) {
    throw InputError("client key for '" + EscapeForDisplay(client_id) +
                     "': not a client id (1-64 of A-Z a-z 0-9 _ . -)");
  }
  clients_.insert_or_assign(client_id, key);
}

const MacKey* KeyRing::KeyFor(std::string_view client_id) const {
  const auto it = clients_.find(client_id);
  if (it != clients_.end()) return &it->second;
  return room_ ? &*room_ : nullptr;
}

const MacKey* KeyRing::ServiceKey() const {
  if (service_) return &*service_;
  return room_ ? &*room_ : nullptr;
}

MacKey NewRandomKey() {
  InitSodium();
  std::array<uint8_t, kKeyBytes> bytes{};
  randombytes_buf(bytes.data(), bytes.size());
  MacKey key(bytes);
  sodium_memzero(bytes.data(), bytes.size());
  return key;
}

BoxKeyPair::~BoxKeyPair() { sodium_memzero(secret_key.data(), secret_key.size()); }

BoxKeyPair NewBoxKeyPair() {
  static_assert(crypto_box_PUBLICKEYBYTES == kBoxPublicKeyBytes);
  static_assert(crypto_box_SECRETKEYBYTES == 32);
  static_assert(crypto_box_SEALBYTES + kKeyBytes == kSealedKeyBytes);
  InitSodium();
  BoxKeyPair pair;
  if (crypto_box_keypair(pair.public_key.data(), pair.secret_key.data()) != 0) {
    throw std::runtime_error("crypto_box_keypair failed");
  }
  return pair;
}

std::vector<uint8_t> SealKey(const MacKey& key, const uint8_t* public_key) {
  InitSodium();
  std::vector<uint8_t> sealed(kSealedKeyBytes);
  if (crypto_box_seal(sealed.data(), key.data(), kKeyBytes, public_key) != 0) {
    throw std::runtime_error("crypto_box_seal failed (not a valid X25519 public key)");
  }
  return sealed;
}

std::optional<MacKey> OpenSealedKey(const uint8_t* sealed, size_t size, const BoxKeyPair& pair) {
  InitSodium();
  if (size != kSealedKeyBytes) return std::nullopt;
  std::array<uint8_t, kKeyBytes> bytes{};
  if (crypto_box_seal_open(bytes.data(), sealed, size, pair.public_key.data(),
                           pair.secret_key.data()) != 0) {
    return std::nullopt;
  }
  MacKey key(bytes);
  sodium_memzero(bytes.data(), bytes.size());
  return key;
}

}  // namespace sweptccd
