// HMAC-SHA256 signing of encoded messages, key files and the key ring.

#include "msgs/signing.h"

#include <gtest/gtest.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "core/errors.h"
#include "tests/msgs/msgs_test_util.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;
using testing::RandomMessages;

const char kHexA[] = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const char kHexB[] = "ff0102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const char kKnownMacHex[] = "cb515b615e351d207bba1e0f29f9786034fb3a9c6c2660b76826d6d41d9fd88a";

class KeyFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sweptccd_signing_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text, mode_t mode) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    chmod(path.c_str(), mode);
    return path;
  }
  std::string LoadProblem(const std::string& path) {
    try {
      LoadKeyFile(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST(Signing, SignVerifyRoundTripAndEveryFlippedBitFails) {
  const MacKey key = ParseKeyHex(kHexA, "test");
  RandomMessages r(31);
  tracker_pose_t m = r.Pose();
  std::vector<uint8_t> bytes = EncodeSigned(m, &key);
  EXPECT_TRUE(VerifyEncoded(bytes.data(), bytes.size(), key));
  for (size_t i = 0; i < bytes.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      bytes[i] ^= static_cast<uint8_t>(1 << bit);
      EXPECT_FALSE(VerifyEncoded(bytes.data(), bytes.size(), key)) << "byte " << i << " bit " << bit;
      bytes[i] ^= static_cast<uint8_t>(1 << bit);
    }
  }
  EXPECT_TRUE(VerifyEncoded(bytes.data(), bytes.size(), key));
}

// The mac is computed with OpenSSL from precomputed pads; libsodium's
// crypto_auth_hmacsha256 (the implementation before) is its twin: seeded
// random keys and every length from 32 to 4160 bytes (0-4128 signed), so
// every SHA-256 block boundary and padding case is crossed.
TEST(Signing, MacEqualsLibsodiumHmacOnRandomKeysAndEveryLength) {
  ASSERT_GE(sodium_init(), 0);
  std::mt19937_64 rng(20261124);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t size = kMacBytes; size <= 4160; ++size) {
    std::array<uint8_t, kKeyBytes> k{};
    for (uint8_t& b : k) b = static_cast<uint8_t>(byte(rng));
    const MacKey key(k);
    std::vector<uint8_t> bytes(size);
    for (uint8_t& b : bytes) b = static_cast<uint8_t>(byte(rng));
    SignEncoded(bytes.data(), bytes.size(), &key);
    uint8_t twin[kMacBytes];
    crypto_auth_hmacsha256(twin, bytes.data(), size - kMacBytes, k.data());
    ASSERT_EQ(std::memcmp(twin, bytes.data() + size - kMacBytes, kMacBytes), 0) << "size " << size;
    ASSERT_TRUE(VerifyEncoded(bytes.data(), bytes.size(), key)) << "size " << size;
    ASSERT_EQ(crypto_auth_hmacsha256_verify(twin, bytes.data(), size - kMacBytes, k.data()), 0);
  }
}

// A known answer, independent of both libraries: HMAC-SHA256 with the key
// 00 01 .. 1f over "sweptccd" (Python: hmac.new(bytes(range(32)),
// b"sweptccd", hashlib.sha256).hexdigest()).
TEST(Signing, MacOfAKnownMessage) {
  const MacKey key = ParseKeyHex(kHexA, "a");
  std::vector<uint8_t> bytes = {'s', 'w', 'e', 'p', 't', 'c', 'c', 'd'};
  bytes.resize(bytes.size() + kMacBytes);
  SignEncoded(bytes.data(), bytes.size(), &key);
  char hex[2 * kMacBytes + 1];
  sodium_bin2hex(hex, sizeof(hex), bytes.data() + 8, kMacBytes);
  EXPECT_STREQ(hex, kKnownMacHex);
}

// One key (its shared pads) used by several threads at once, as the
// daemon's workers sign and its LCM thread verifies: every mac right.
TEST(Signing, OneKeySignsAndVerifiesOnManyThreadsAtOnce) {
  const MacKey key = ParseKeyHex(kHexB, "b");
  RandomMessages r(34);
  const std::vector<uint8_t> reference = EncodeSigned(r.Pose(), &key);
  std::vector<int> wrong(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      const MacKey copy = key;  // Copies share the pads.
      for (int i = 0; i < 2000; ++i) {
        std::vector<uint8_t> bytes = reference;
        std::memset(bytes.data() + bytes.size() - kMacBytes, 0, kMacBytes);
        SignEncoded(bytes.data(), bytes.size(), (i % 2) ? &copy : &key);
        if (bytes != reference || !VerifyEncoded(bytes.data(), bytes.size(), copy)) ++wrong[t];
      }
    });
  }
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < 4; ++t) EXPECT_EQ(wrong[t], 0) << "thread " << t;
}

TEST(Signing, WrongKeyAndUnsignedFail) {
  const MacKey a = ParseKeyHex(kHexA, "a");
  const MacKey b = ParseKeyHex(kHexB, "b");
  RandomMessages r(32);
  const std::vector<uint8_t> signed_a = EncodeSigned(r.Status(), &a);
  EXPECT_FALSE(VerifyEncoded(signed_a.data(), signed_a.size(), b));
  const std::vector<uint8_t> unsigned_bytes = EncodeSigned(r.Rejection(), nullptr);
  EXPECT_FALSE(VerifyEncoded(unsigned_bytes.data(), unsigned_bytes.size(), a));
  for (size_t i = unsigned_bytes.size() - kMacBytes; i < unsigned_bytes.size(); ++i) {
    EXPECT_EQ(unsigned_bytes[i], 0);
  }
  EXPECT_FALSE(VerifyEncoded(signed_a.data(), 31, a));
}

TEST(Signing, TheMacIsTheLastFieldOfTheDecodedMessage) {
  const MacKey key = ParseKeyHex(kHexA, "a");
  contact_event_t e = RandomMessages(33).Contact();
  const std::vector<uint8_t> bytes = EncodeSigned(e, &key);
  contact_event_t back;
  ASSERT_EQ(back.decode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  EXPECT_EQ(std::memcmp(back.mac, bytes.data() + bytes.size() - kMacBytes, kMacBytes), 0);
}

TEST(Signing, ParseKeyHexRefusesBadKeys) {
  EXPECT_NO_THROW(ParseKeyHex(std::string("  ") + kHexA + "\n", "k"));
  EXPECT_THROW(ParseKeyHex(std::string(kHexA).substr(2), "k"), InputError);
  EXPECT_THROW(ParseKeyHex(std::string(kHexA) + "00", "k"), InputError);
  std::string bad = kHexA;
  bad[10] = 'g';
  try {
    ParseKeyHex(bad, "where.key");
    FAIL() << "accepted a non-hex key";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("where.key: the key holds characters other than hex"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(KeyFileTest, AcceptsMode600AndTrimsWhitespace) {
  const MacKey from_file = LoadKeyFile(Write("ok.key", std::string(kHexA) + "\n", 0600));
  const MacKey direct = ParseKeyHex(kHexA, "direct");
  EXPECT_EQ(std::memcmp(from_file.data(), direct.data(), kKeyBytes), 0);
  EXPECT_EQ(LoadProblem(Write("ro.key", kHexA, 0400)), "");
}

TEST_F(KeyFileTest, RefusesFilesOthersCanReadOrWrite) {
  for (const mode_t mode : {0644, 0640, 0604, 0620, 0602}) {
    const std::string path = Write("open.key", kHexA, mode);
    const std::string problem = LoadProblem(path);
    EXPECT_NE(problem.find("run `chmod 600 " + path + "`"), std::string::npos)
        << std::oct << mode << ": " << problem;
    fs::remove(path);
  }
}

TEST_F(KeyFileTest, RefusesDirectoriesMissingFilesAndBadContent) {
  const fs::path sub = dir_ / "sub";
  fs::create_directories(sub);
  chmod(sub.c_str(), 0700);
  EXPECT_NE(LoadProblem(sub.string()).find("not a regular file"), std::string::npos);
  const std::string fifo = (dir_ / "fifo.key").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_NE(LoadProblem(fifo).find("not a regular file"), std::string::npos);  // Never blocks.
  const std::string link = (dir_ / "link.key").string();
  fs::create_symlink(Write("target.key", kHexA, 0600), link);
  EXPECT_EQ(LoadProblem(link), "");
  EXPECT_NE(LoadProblem((dir_ / "missing").string()).find("cannot open"), std::string::npos);
  EXPECT_NE(LoadProblem(Write("short.key", "abcd", 0600)).find("4 characters long, not 64"),
            std::string::npos);
  EXPECT_NE(LoadProblem(Write("big.key", std::string(5000, 'a'), 0600)).find("over 1 KiB"),
            std::string::npos);
}

TEST_F(KeyFileTest, WriteNewKeyFileMakesAMode600KeyAndNeverOverwrites) {
  const std::string path = (dir_ / "new.key").string();
  WriteNewKeyFile(path);
  struct stat st {};
  ASSERT_EQ(stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const MacKey key = LoadKeyFile(path);
  EXPECT_THROW(WriteNewKeyFile(path), InputError);
  const std::string other = (dir_ / "other.key").string();
  WriteNewKeyFile(other);
  EXPECT_NE(std::memcmp(LoadKeyFile(other).data(), key.data(), kKeyBytes), 0);
}

TEST(KeyRing, ClientKeyElseRoomKeyAndServiceKeyDefaultsToRoom) {
  const MacKey a = ParseKeyHex(kHexA, "a");
  const MacKey b = ParseKeyHex(kHexB, "b");
  KeyRing ring;
  EXPECT_EQ(ring.KeyFor("alice"), nullptr);
  EXPECT_EQ(ring.ServiceKey(), nullptr);
  ring.SetRoomKey(a);
  ring.SetClientKey("alice", b);
  EXPECT_EQ(std::memcmp(ring.KeyFor("alice")->data(), b.data(), kKeyBytes), 0);
  EXPECT_EQ(std::memcmp(ring.KeyFor("bob")->data(), a.data(), kKeyBytes), 0);
  EXPECT_EQ(std::memcmp(ring.ServiceKey()->data(), a.data(), kKeyBytes), 0);
  ring.SetServiceKey(b);
  EXPECT_EQ(std::memcmp(ring.ServiceKey()->data(), b.data(), kKeyBytes), 0);
  EXPECT_THROW(ring.SetClientKey("bad id", a), InputError);
}

}  // namespace
}  // namespace sweptccd
