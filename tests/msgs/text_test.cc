#include "msgs/text.h"

#include <gtest/gtest.h>

namespace sweptccd {
namespace {

TEST(ClientIdRule, AcceptsOneTo64OfTheAlphabet) {
  EXPECT_TRUE(IsValidClientId("alice"));
  EXPECT_TRUE(IsValidClientId("A-z_0.9"));
  EXPECT_TRUE(IsValidClientId(std::string(64, 'a')));
  EXPECT_FALSE(IsValidClientId(""));
  EXPECT_FALSE(IsValidClientId(std::string(65, 'a')));
  EXPECT_FALSE(IsValidClientId("alice\n"));
  EXPECT_FALSE(IsValidClientId("al ice"));
  EXPECT_FALSE(IsValidClientId("al/ice"));
  EXPECT_FALSE(IsValidClientId("\x1b[31m"));
  EXPECT_FALSE(IsValidClientId(std::string("a\0b", 3)));
  EXPECT_FALSE(IsValidClientId("caf\xc3\xa9"));
}

TEST(EscapeForDisplay, PrintableAsIsEverythingElseEscaped) {
  EXPECT_EQ(EscapeForDisplay("alice 1.0-x_y"), "alice 1.0-x_y");
  EXPECT_EQ(EscapeForDisplay("a\nb"), "a\\nb");
  EXPECT_EQ(EscapeForDisplay("\x1b[31mred"), "\\x1b[31mred");
  EXPECT_EQ(EscapeForDisplay("back\\slash"), "back\\\\slash");
  EXPECT_EQ(EscapeForDisplay("\r\t\x7f\xff"), "\\r\\t\\x7f\\xff");
  EXPECT_EQ(EscapeForDisplay(std::string("a\0b", 3)), "a\\x00b");
}

TEST(EscapeForDisplay, ForgedLogLineStaysOneLine) {
  const std::string forged = "x\n[12:00:00.000] [info] contact alice\x1b[0m";
  const std::string shown = EscapeForDisplay(forged);
  EXPECT_EQ(shown.find('\n'), std::string::npos);
  EXPECT_EQ(shown.find('\x1b'), std::string::npos);
  for (const char c : shown) EXPECT_TRUE(c >= 0x20 && c < 0x7f);
}

TEST(EscapeForDisplay, LongTextIsCut) {
  EXPECT_EQ(EscapeForDisplay(std::string(10, 'a'), 4), "aaaa...(10 bytes)");
  EXPECT_EQ(EscapeForDisplay(std::string(4, 'a'), 4), "aaaa");
}

}  // namespace
}  // namespace sweptccd
