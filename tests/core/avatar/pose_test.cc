// Tests for core/pose.h: pose line parsing (SPEC section 2) and the pairing
// rule, against a twin written here from the SPEC text.

#include "core/avatar/pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace sweptccd {
namespace {

std::string Line(const std::string& utime, const std::vector<std::string>& links) {
  std::string s = "{\"utime\": " + utime + ", \"links\": [";
  for (size_t i = 0; i < links.size(); ++i) s += (i ? ", " : "") + links[i];
  return s + "]}";
}

constexpr char kIdentity[] = "[0, 0, 0, 1, 0, 0, 0]";

std::optional<Pose> Parse(const std::string& line, int num_links, std::string* error) {
  error->clear();
  std::optional<Pose> p = ParsePoseLine(line, num_links, error);
  if (p) {
    EXPECT_EQ(*error, "") << line;
  } else {
    EXPECT_NE(*error, "") << "a refusal must say why: " << line;
  }
  return p;
}

TEST(PoseTest, ParsesValidLine) {
  std::string error;
  const auto p = Parse(Line("1000000", {"[1, 2, 3, 1, 0, 0, 0]", "[-0.5, 0.25, 1e-3, 0, 0, 0, 1]"}),
                       2, &error);
  ASSERT_TRUE(p.has_value()) << error;
  EXPECT_EQ(p->utime, 1000000);
  ASSERT_EQ(p->links.size(), 2u);
  EXPECT_EQ(p->links[0].p, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(p->links[0].q.coeffs(), Eigen::Quaterniond(1, 0, 0, 0).coeffs());
  EXPECT_EQ(p->links[1].p, Eigen::Vector3d(-0.5, 0.25, 1e-3));
  // [w, x, y, z] order: w = 0, z = 1.
  EXPECT_EQ(p->links[1].q.w(), 0);
  EXPECT_EQ(p->links[1].q.z(), 1);
  // Extra fields and whitespace are fine.
  EXPECT_TRUE(
      Parse("  {\"links\": [[0,0,0,1,0,0,0]], \"note\": \"x\", \"utime\": 5}  ", 1, &error));
}

TEST(PoseTest, NormalisesQuaternions) {
  std::mt19937_64 g(0x905e0001);
  std::normal_distribution<double> n(0, 1);
  for (int c = 0; c < 20000; ++c) {
    const double scale = std::pow(10.0, std::uniform_real_distribution<double>(-5.9, 100)(g));
    const double w = n(g), x = n(g), y = n(g), z = n(g);
    std::ostringstream s;
    s.precision(17);
    s << "[0, 0, 0, " << w * scale << ", " << x * scale << ", " << y * scale << ", " << z * scale
      << "]";
    std::string error;
    const auto p = Parse(Line("7", {s.str()}), 1, &error);
    const double norm = std::sqrt(w * w + x * x + y * y + z * z) * scale;
    if (norm < 1.0001e-6) continue;  // Too close to the threshold to call here.
    ASSERT_TRUE(p.has_value()) << s.str() << ": " << error;
    const Eigen::Quaterniond& q = p->links[0].q;
    EXPECT_NEAR(q.norm(), 1.0, 1e-15) << s.str();
    const double len = std::sqrt(w * w + x * x + y * y + z * z);
    EXPECT_NEAR(q.w(), w / len, 1e-14) << s.str();
    EXPECT_NEAR(q.x(), x / len, 1e-14) << s.str();
    EXPECT_NEAR(q.y(), y / len, 1e-14) << s.str();
    EXPECT_NEAR(q.z(), z / len, 1e-14) << s.str();
  }
  std::string error;
  const auto p = Parse(Line("7", {"[0, 0, 0, 2, 0, 0, 0]"}), 1, &error);
  ASSERT_TRUE(p);
  EXPECT_EQ(p->links[0].q.w(), 1.0);
}

// Regression: a finite quaternion with huge components (norm not below 1e-6,
// so valid per SPEC) must normalise to a unit quaternion. q.norm() overflows
// to inf when the squares overflow, and dividing by inf leaves [0, 0, 0, 0].
TEST(PoseTest, HugeQuaternionNormalisesToUnit) {
  std::string error;
  const auto p = Parse(Line("7", {"[0, 0, 0, 1e200, 1e200, 0, 0]"}), 1, &error);
  ASSERT_TRUE(p.has_value()) << error;
  EXPECT_NEAR(p->links[0].q.norm(), 1.0, 1e-15);
  EXPECT_NEAR(p->links[0].q.w(), std::sqrt(0.5), 1e-15);
  Pose pose;
  pose.links.resize(1);
  pose.links[0].q = Eigen::Quaterniond(0, 0, 3e160, 0);
  const std::string problem = ValidateAndNormalizePose(&pose, 1);
  EXPECT_EQ(problem, "");
  EXPECT_NEAR(pose.links[0].q.y(), 1.0, 1e-15);
}

TEST(PoseTest, RefusesTinyQuaternionNorm) {
  std::string error;
  for (const char* q :
       {"[0, 0, 0, 0, 0, 0, 0]", "[0, 0, 0, 1e-7, 0, 0, 0]", "[0, 0, 0, 5e-7, 5e-7, 0, 0]",
        "[0, 0, 0, 0, 0, 0, -9.9e-7]", "[0, 0, 0, 1e-200, 1e-200, 1e-200, 1e-200]"}) {
    SCOPED_TRACE(q);
    EXPECT_FALSE(Parse(Line("7", {kIdentity, q}), 2, &error).has_value());
    EXPECT_NE(error.find("link 1"), std::string::npos) << error;
  }
  for (const char* q : {"[0, 0, 0, 1.01e-6, 0, 0, 0]", "[0, 0, 0, 0, 0, -2e-6, 0]"}) {
    SCOPED_TRACE(q);
    const auto p = Parse(Line("7", {kIdentity, q}), 2, &error);
    ASSERT_TRUE(p.has_value()) << error;
    EXPECT_NEAR(p->links[1].q.norm(), 1.0, 1e-15);
  }
  // Non-finite numbers, set programmatically (JSON has none).
  for (int field = 0; field < 7; ++field) {
    Pose pose;
    pose.links.resize(2);
    const double bad = field % 2 ? std::numeric_limits<double>::quiet_NaN()
                                 : std::numeric_limits<double>::infinity();
    if (field < 3) {
      pose.links[1].p[field] = bad;
    } else {
      pose.links[1].q.coeffs()[field - 3] = bad;
    }
    const std::string problem = ValidateAndNormalizePose(&pose, 2);
    EXPECT_NE(problem.find("link 1"), std::string::npos) << field << ": " << problem;
  }
  Pose pose;
  pose.links.resize(3);
  EXPECT_NE(ValidateAndNormalizePose(&pose, 2), "");
}

TEST(PoseTest, RefusesGarbage) {
  for (const char* line :
       {"", "hello", "{", "}", "[1, 2]", "null", "42", "\"utime\"", "{\"utime\": 1, \"links\": [",
        "{\"utime\": 1, \"links\": [[0,0,0,1,0,0,0]]} trailing", "\xff\xfe",
        "{\"utime\": 1e999, "
        "\"links\": [[0,0,0,1,0,0,0]]}",
        "{\"utime\": 1, \"links\": [[0,0,0,1e999,0,0,0]]}"}) {
    std::string error;
    SCOPED_TRACE(line);
    EXPECT_FALSE(Parse(line, 1, &error).has_value());
  }
}

// nlohmann::json stops at a NUL byte and accepts the JSON before it: a valid
// line, a NUL and garbage must still be refused (SPEC section 2: the line is
// not one JSON object).
TEST(PoseTest, RefusesAValidLineFollowedByANulByte) {
  const std::string valid = Line("1", {kIdentity});
  std::string error;
  ASSERT_TRUE(Parse(valid, 1, &error).has_value());
  for (const std::string& tail : {std::string(1, '\0'), std::string("\0garbage", 8)}) {
    EXPECT_FALSE(Parse(valid + tail, 1, &error).has_value());
    EXPECT_NE(error.find("NUL byte at offset " + std::to_string(valid.size())), std::string::npos)
        << error;
  }
}

TEST(PoseTest, RefusesWrongLinkCount) {
  std::string error;
  EXPECT_FALSE(Parse(Line("1", {kIdentity}), 2, &error).has_value());
  EXPECT_NE(error.find("2"), std::string::npos) << error;
  EXPECT_FALSE(Parse(Line("1", {kIdentity, kIdentity, kIdentity}), 2, &error).has_value());
  EXPECT_FALSE(Parse(Line("1", {}), 2, &error).has_value());
  EXPECT_FALSE(Parse("{\"utime\": 1, \"links\": {}}", 1, &error).has_value());
  EXPECT_FALSE(Parse("{\"utime\": 1}", 1, &error).has_value());
  EXPECT_TRUE(Parse(Line("1", {kIdentity, kIdentity}), 2, &error).has_value()) << error;
}

TEST(PoseTest, RefusesNonNumberEntries) {
  for (const char* e :
       {"[0, 0, \"0\", 1, 0, 0, 0]", "[0, 0, 0, null, 0, 0, 0]", "[0, 0, 0, 1, 0, 0, true]",
        "[0, 0, 0, 1, 0, [0], 0]", "[0, 0, 0, 1, 0, 0]", "[0, 0, 0, 1, 0, 0, 0, 0]", "[]",
        "{\"p\": [0, 0, 0]}", "\"identity\"", "7"}) {
    std::string error;
    SCOPED_TRACE(e);
    EXPECT_FALSE(Parse(Line("1", {kIdentity, e}), 2, &error).has_value());
    EXPECT_NE(error.find("link 1"), std::string::npos) << error;
  }
}

TEST(PoseTest, Utime) {
  std::string error;
  auto utime_of = [&](const std::string& u) -> std::optional<int64_t> {
    const auto p = Parse(Line(u, {kIdentity}), 1, &error);
    if (!p) return std::nullopt;
    return p->utime;
  };
  EXPECT_EQ(utime_of("1000000"), 1000000);
  EXPECT_EQ(utime_of("1000000.0"), 1000000);
  EXPECT_EQ(utime_of("1e6"), 1000000);
  EXPECT_EQ(utime_of("0"), 0);
  EXPECT_EQ(utime_of("-5"), -5);
  EXPECT_EQ(utime_of("9223372036854775807"), std::numeric_limits<int64_t>::max());
  EXPECT_EQ(utime_of("1700000000123456"), 1700000000123456);
  EXPECT_FALSE(utime_of("9223372036854775808"));  // Beyond int64.
  EXPECT_FALSE(utime_of("1e19"));
  EXPECT_FALSE(utime_of("1000000.5"));
  EXPECT_FALSE(utime_of("\"1000000\""));
  EXPECT_FALSE(utime_of("null"));
  EXPECT_FALSE(utime_of("[1]"));
  EXPECT_FALSE(Parse("{\"links\": [[0,0,0,1,0,0,0]]}", 1, &error).has_value());
  EXPECT_NE(error.find("utime"), std::string::npos) << error;
}

TEST(PoseTest, JsonLineRoundTrip) {
  std::mt19937_64 g(0x905e0002);
  std::normal_distribution<double> n(0, 1);
  std::uniform_int_distribution<int64_t> t(-(int64_t{1} << 62), int64_t{1} << 62);
  for (int c = 0; c < 2000; ++c) {
    const int links = std::uniform_int_distribution<int>(1, 30)(g);
    Pose pose;
    pose.utime = t(g);
    pose.links.resize(links);
    for (LinkPose& lp : pose.links) {
      lp.p = Eigen::Vector3d(n(g), n(g), n(g)) * 100;
      lp.q = Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized();
    }
    std::string error;
    const auto back = Parse(PoseToJsonLine(pose), links, &error);
    ASSERT_TRUE(back.has_value()) << error;
    EXPECT_EQ(back->utime, pose.utime);
    for (int i = 0; i < links; ++i) {
      EXPECT_EQ(back->links[i].p, pose.links[i].p);  // Bit-exact.
      EXPECT_LT((back->links[i].q.coeffs() - pose.links[i].q.coeffs()).norm(), 1e-15);
    }
  }
}

// ---------------------------------------------------------------------------
// The pairing rule.

// What one counted line is, as the test generates it.
struct LineSpec {
  bool valid = false;
  int64_t utime = 0;
  int id = 0;  // Stored in links[0].p.x(), to tell poses apart.
};

struct Expected {
  int64_t pair;
  bool valid;
  int id0 = -1, id1 = -1;         // For valid records.
  std::optional<int64_t> utime1;  // Known when the line's pose is valid.
};

// The twin, from SPEC section 2 as the brief reads it: the first counted line
// yields no record; a valid pose becomes the anchor when it forms a pair or
// when there is no anchor yet; an invalid or non-increasing pose never does.
std::vector<Expected> Twin(const std::vector<LineSpec>& lines) {
  std::vector<Expected> out;
  const LineSpec* anchor = nullptr;
  for (size_t k = 0; k < lines.size(); ++k) {
    const LineSpec& line = lines[k];
    if (k == 0) {
      if (line.valid) anchor = &line;
      continue;
    }
    Expected e{static_cast<int64_t>(k) - 1, false, -1, -1, std::nullopt};
    if (line.valid) e.utime1 = line.utime;
    if (line.valid && anchor != nullptr && line.utime > anchor->utime) {
      e.valid = true;
      e.id0 = anchor->id;
      e.id1 = line.id;
    }
    if (line.valid && (anchor == nullptr || e.valid)) anchor = &line;
    out.push_back(e);
  }
  return out;
}

Pose MakePose(const LineSpec& spec, int num_links) {
  Pose p;
  p.utime = spec.utime;
  p.links.resize(num_links);
  p.links[0].p.x() = spec.id;
  return p;
}

std::vector<LineSpec> RandomSequence(std::mt19937_64& g) {
  std::uniform_int_distribution<int> len(1, 60), pick(0, 9);
  std::vector<LineSpec> lines(len(g));
  int64_t t = std::uniform_int_distribution<int64_t>(-1000, 1000000)(g);
  for (size_t k = 0; k < lines.size(); ++k) {
    LineSpec& l = lines[k];
    l.id = static_cast<int>(k);
    const int r = pick(g);
    l.valid = r >= 3;  // 30% invalid.
    if (r == 3) {
      l.utime = t;  // Equal to the last generated.
    } else if (r == 4) {
      l.utime = t - std::uniform_int_distribution<int64_t>(1, 50000)(g);  // Going back.
    } else {
      t += std::uniform_int_distribution<int64_t>(1, 20000)(g);
      l.utime = t;
    }
  }
  return lines;
}

TEST(PosePairerTest, MatchesSpecTwinOnRandomSequences) {
  std::mt19937_64 g(0x905e0003);
  int64_t records = 0, valid_records = 0;
  for (int c = 0; c < 5000; ++c) {
    const std::vector<LineSpec> lines = RandomSequence(g);
    const std::vector<Expected> want = Twin(lines);
    const int num_links = 1 + c % 3;
    PosePairer pairer;
    size_t next = 0;
    for (size_t k = 0; k < lines.size(); ++k) {
      std::optional<Pose> pose;
      if (lines[k].valid) pose = MakePose(lines[k], num_links);
      const std::optional<PairOutcome> got = pairer.Feed(pose, "bad line " + std::to_string(k));
      SCOPED_TRACE("sequence " + std::to_string(c) + " line " + std::to_string(k));
      if (k == 0) {
        EXPECT_FALSE(got.has_value()) << "the first line yields no record";
        continue;
      }
      ASSERT_TRUE(got.has_value()) << "every line after the first yields a record";
      ASSERT_LT(next, want.size());
      const Expected& e = want[next++];
      ++records;
      EXPECT_EQ(got->pair, static_cast<int64_t>(k) - 1);
      EXPECT_EQ(got->pair, e.pair);
      ASSERT_EQ(got->valid, e.valid);
      EXPECT_EQ(got->utime1, e.utime1);
      if (e.valid) {
        ++valid_records;
        EXPECT_EQ(got->error, "");
        EXPECT_EQ(static_cast<int>(got->pose0.links.at(0).p.x()), e.id0);
        EXPECT_EQ(static_cast<int>(got->pose1.links.at(0).p.x()), e.id1);
        EXPECT_EQ(got->pose0.utime, lines[e.id0].utime);
        EXPECT_EQ(got->pose1.utime, lines[e.id1].utime);
        EXPECT_EQ(got->utime0, lines[e.id0].utime);
        EXPECT_EQ(got->pose1.links.size(), static_cast<size_t>(num_links));
      } else {
        EXPECT_NE(got->error, "");
        if (!lines[k].valid) {
          EXPECT_NE(got->error.find("bad line " + std::to_string(k)), std::string::npos)
              << "the parse error is passed on: " << got->error;
        }
      }
    }
    EXPECT_EQ(next, want.size());
  }
  EXPECT_GT(records, 100000);
  EXPECT_GT(valid_records, 30000);
}

// End to end: text lines (valid, garbage, wrong link count, zero quaternion,
// non-increasing utime) through ParsePoseLine and the pairer.
TEST(PosePairerTest, ParsedLinesFollowTheRule) {
  std::mt19937_64 g(0x905e0004);
  std::uniform_int_distribution<int> bad_kind(0, 4);
  int64_t records = 0;
  for (int c = 0; c < 2000; ++c) {
    const std::vector<LineSpec> lines = RandomSequence(g);
    const std::vector<Expected> want = Twin(lines);
    constexpr int kLinks = 2;
    PosePairer pairer;
    size_t next = 0;
    for (size_t k = 0; k < lines.size(); ++k) {
      const LineSpec& l = lines[k];
      const std::string good = "[" + std::to_string(l.id) + ", 0, 0, 0.5, 0.5, 0.5, 0.5]";
      std::string text;
      if (l.valid) {
        text = Line(std::to_string(l.utime), {good, kIdentity});
      } else {
        switch (bad_kind(g)) {
          case 0:
            text = "not json at all";
            break;
          case 1:
            text = Line(std::to_string(l.utime), {good});
            break;
          case 2:
            text = Line(std::to_string(l.utime), {good, "[0, 0, 0, 0, 0, 0, 0]"});
            break;
          case 3:
            text = Line("\"soon\"", {good, kIdentity});
            break;
          default:
            text = Line(std::to_string(l.utime), {good, "[0, 0, 0, 1, 0, \"x\", 0]"});
            break;
        }
      }
      std::string error;
      std::optional<Pose> pose = ParsePoseLine(text, kLinks, &error);
      ASSERT_EQ(pose.has_value(), l.valid) << text << " " << error;
      const std::optional<PairOutcome> got = pairer.Feed(std::move(pose), error);
      if (k == 0) {
        EXPECT_FALSE(got.has_value());
        continue;
      }
      ASSERT_TRUE(got.has_value());
      const Expected& e = want[next++];
      ++records;
      EXPECT_EQ(got->pair, static_cast<int64_t>(k) - 1);
      ASSERT_EQ(got->valid, e.valid) << "sequence " << c << " line " << k;
      if (e.valid) {
        EXPECT_EQ(got->pose0.links[0].p.x(), e.id0);
        EXPECT_EQ(got->pose1.links[0].p.x(), e.id1);
        EXPECT_NEAR(got->pose1.links[0].q.norm(), 1.0, 1e-15);
      }
    }
  }
  EXPECT_GT(records, 40000);
}

// The stream reader (used by `query` and `render`): blank and whitespace-only
// lines are not counted, the rest is the pairing rule; a bad first line is
// kept as first_line_error with its line number.
TEST(PoseStreamReaderTest, SkipsBlankLinesAndPairsTheRest) {
  std::mt19937_64 g(0x905e0005);
  int64_t records = 0;
  for (int c = 0; c < 300; ++c) {
    const std::vector<LineSpec> lines = RandomSequence(g);
    const std::vector<Expected> want = Twin(lines);
    std::string text;
    std::vector<int> line_of(lines.size());
    int line_no = 0;
    for (size_t k = 0; k < lines.size(); ++k) {
      if (g() % 3 == 0) {
        text += g() % 2 ? "\n" : " \t\r\n";
        ++line_no;
      }
      const LineSpec& l = lines[k];
      const std::string good = "[" + std::to_string(l.id) + ", 0, 0, 0.5, 0.5, 0.5, 0.5]";
      text += (l.valid ? Line(std::to_string(l.utime), {good, kIdentity}) : "not json") + "\n";
      line_of[k] = ++line_no;
    }
    std::istringstream in(text);
    PoseStreamReader reader(in, 2);
    size_t next = 0;
    while (std::optional<PairOutcome> got = reader.Next()) {
      ASSERT_LT(next, want.size());
      const Expected& e = want[next];
      EXPECT_EQ(got->pair, static_cast<int64_t>(next));
      ASSERT_EQ(got->valid, e.valid) << "sequence " << c << " record " << next;
      if (e.valid) {
        EXPECT_EQ(got->pose0.links[0].p.x(), e.id0);
        EXPECT_EQ(got->pose1.links[0].p.x(), e.id1);
      } else if (!lines[next + 1].valid) {
        EXPECT_EQ(got->error.rfind("invalid pose: line " + std::to_string(line_of[next + 1]) + ": ",
                                   0),
                  0u)
            << got->error;
      }
      ++next;
      ++records;
    }
    EXPECT_EQ(next, want.size());
    EXPECT_FALSE(reader.bad());
    if (lines[0].valid) {
      EXPECT_EQ(reader.first_line_error(), "");
    } else {
      EXPECT_EQ(reader.first_line_error().rfind("line " + std::to_string(line_of[0]) + ": ", 0), 0u)
          << reader.first_line_error();
    }
  }
  EXPECT_GT(records, 3000);
}

// A line longer than the cap is an invalid pose (SPEC 2), read to its newline
// without being kept: the next lines are read as usual, with their numbers.
TEST(PoseStreamReaderTest, OverlongLineIsAnInvalidPoseAndReadingGoesOn) {
  const std::string good0 = Line("1000", {kIdentity});
  const std::string good2 = Line("3000", {kIdentity});
  const std::string huge = Line("2000", {kIdentity}) + std::string(5000, ' ');
  const std::string text = good0 + "\n" + huge + "\n\n" + good2 + "\n";
  std::istringstream in(text);
  PoseStreamReader reader(in, 1, /*max_line_bytes=*/200);
  std::optional<PairOutcome> first = reader.Next();
  ASSERT_TRUE(first.has_value());
  EXPECT_FALSE(first->valid);
  EXPECT_EQ(first->error,
            "invalid pose: line 2: longer than the cap of 200 bytes for a pose of 1 links "
            "(skipped to its end)");
  std::optional<PairOutcome> second = reader.Next();
  ASSERT_TRUE(second.has_value());
  EXPECT_TRUE(second->valid) << second->error;
  EXPECT_EQ(second->pair, 1);
  EXPECT_EQ(second->pose0.utime, 1000);
  EXPECT_EQ(second->pose1.utime, 3000);
  EXPECT_FALSE(reader.Next().has_value());
  // An overlong line of whitespace only is still blank.
  std::istringstream blank(good0 + "\n" + std::string(1000, ' ') + "\n" + good2 + "\n");
  PoseStreamReader blank_reader(blank, 1, 200);
  std::optional<PairOutcome> only = blank_reader.Next();
  ASSERT_TRUE(only.has_value());
  EXPECT_TRUE(only->valid) << only->error;
  EXPECT_EQ(only->pair, 0);
}

// The bounded line reader against std::getline and the blank rule, on seeded
// random text (lines of random lengths around the cap, whitespace, a missing
// final newline): every counted line comes back whole, or flagged over the cap.
TEST(PoseLineReaderTest, MatchesGetlineTwinOnRandomText) {
  std::mt19937_64 g(0xb0bd5);
  const char alphabet[] = " \t\rx{}0";
  for (int c = 0; c < 500; ++c) {
    std::string text;
    const int lines = static_cast<int>(g() % 8);
    for (int k = 0; k < lines; ++k) {
      const int len = static_cast<int>(g() % 40);
      for (int i = 0; i < len; ++i) text += alphabet[g() % (sizeof(alphabet) - 1)];
      if (k + 1 < lines || g() % 2) text += '\n';
    }
    const uint64_t cap = 1 + g() % 30;
    std::istringstream twin(text);
    std::istringstream in(text);
    PoseLineReader reader(in, 1, cap);
    std::string line;
    int64_t number = 0;
    while (std::getline(twin, line)) {
      ++number;
      if (line.find_first_not_of(" \t\r\n\f\v") == std::string::npos) continue;
      std::optional<PoseLine> got = reader.Next();
      ASSERT_TRUE(got.has_value()) << "case " << c;
      EXPECT_EQ(got->line_number, number);
      ASSERT_FALSE(got->pose.has_value());
      const bool over = line.size() > cap;
      EXPECT_EQ(got->error.find("longer than the cap") != std::string::npos, over)
          << "case " << c << ": " << got->error;
    }
    EXPECT_FALSE(reader.Next().has_value()) << "case " << c;
    EXPECT_FALSE(reader.bad());
  }
}

// A folder opens as an ifstream but every read fails (EISDIR), and
// libstdc++'s filebuf throws where istream's reads set badbit: the reader
// ends with bad(), never an exception (fuzz_world ended the process so).
TEST(PoseLineReaderTest, AFolderIsABadStreamNotAnException) {
  std::ifstream folder(::testing::TempDir(), std::ios::binary);
  ASSERT_TRUE(folder.is_open());
  PoseStreamReader reader(folder, 1);
  std::optional<PairOutcome> pair;
  EXPECT_NO_THROW(pair = reader.Next());
  EXPECT_FALSE(pair.has_value());
  EXPECT_TRUE(reader.bad());
}

TEST(PoseLineReaderTest, DefaultCapGrowsWithTheLinkCount) {
  EXPECT_EQ(DefaultMaxPoseLineBytes(1), 4096u + 7 * 64);
  EXPECT_EQ(DefaultMaxPoseLineBytes(31), 4096u + 31 * 7 * 64);
  EXPECT_EQ(DefaultMaxPoseLineBytes(-1), DefaultMaxPoseLineBytes(256));
  // A real line of 31 links, written with full precision, fits easily.
  Pose pose;
  pose.utime = 1234567890123;
  pose.links.resize(31);
  for (LinkPose& l : pose.links) {
    l.p = {-123.456789012345678, 0.1234567890123456, -1e-300};
    l.q = Eigen::Quaterniond(-0.123456789012345, 0.98765432109876, -1e-17, 0.3);
  }
  EXPECT_LT(PoseToJsonLine(pose).size() * 2, DefaultMaxPoseLineBytes(31));
}

// With num_links < 0 the first pose fixes the count; lines are kept as
// written (not normalised), fractional-but-integral utimes accepted.
TEST(PoseLineReaderTest, LearnsTheLinkCountAndKeepsPosesAsWritten) {
  std::istringstream in(Line("1000.0", {"[1, 2, 3, 2, 0, 0, 0]", kIdentity}) + "\n" +
                        Line("2000", {kIdentity}) + "\n" +
                        Line("3000", {kIdentity, "[0, 0, 0, 0, 0, 0, 0]"}) + "\n");
  PoseLineReader reader(in, -1);
  std::optional<PoseLine> a = reader.Next();
  ASSERT_TRUE(a && a->pose) << (a ? a->error : "end");
  EXPECT_EQ(reader.num_links(), 2);
  EXPECT_EQ(a->pose->utime, 1000);
  EXPECT_EQ(a->pose->links[0].q.w(), 2.0);  // As written.
  std::optional<PoseLine> b = reader.Next();
  ASSERT_TRUE(b.has_value());
  EXPECT_FALSE(b->pose.has_value());
  EXPECT_EQ(b->error, "line 2: 'links' has 1 entries, the skeleton has 2");
  std::optional<PoseLine> c = reader.Next();
  ASSERT_TRUE(c && c->pose) << (c ? c->error : "end");  // A zero quaternion is structurally fine.
}

// A few hand-written sequences, as named regressions of the rule.
TEST(PosePairerTest, HandWrittenSequences) {
  auto run = [](const std::vector<std::pair<bool, int64_t>>& seq) {
    PosePairer pairer;
    std::string got;
    for (size_t k = 0; k < seq.size(); ++k) {
      std::optional<Pose> pose;
      if (seq[k].first) {
        pose = Pose();
        pose->utime = seq[k].second;
        pose->links.resize(1);
      }
      const auto out = pairer.Feed(pose, "bad");
      if (k == 0) continue;
      got += out->valid ? "(" + std::to_string(out->pose0.utime) + "," +
                              std::to_string(out->pose1.utime) + ")"
                        : "x";
    }
    return got;
  };
  // Invalid first line: the next valid pose has nothing to pair with, then anchors.
  EXPECT_EQ(run({{false, 0}, {true, 10}, {true, 20}}), "x(10,20)");
  // An equal utime is not greater: invalid, and it does not become the anchor.
  EXPECT_EQ(run({{true, 10}, {true, 10}, {true, 20}}), "x(10,20)");
  // Going back in time: invalid; the next pose pairs with the last valid one.
  EXPECT_EQ(run({{true, 10}, {true, 5}, {true, 7}, {true, 11}}), "xx(10,11)");
  // An invalid pose between two valid ones.
  EXPECT_EQ(run({{true, 10}, {false, 0}, {true, 30}}), "x(10,30)");
  // A single line: no record at all.
  EXPECT_EQ(run({{true, 10}}), "");
  PosePairer p;
  EXPECT_FALSE(p.has_anchor());
}

// FindPoseProblem against a twin written here from SPEC section 2 and the
// documented order (count; then per link: non-finite position x, y, z, then
// quaternion w, x, y, z; a coordinate beyond 1e9 m; a norm below 1e-6), on
// random poses with spoiled numbers; ValidateAndNormalizePose words it.
TEST(FindPoseProblemTest, FirstProblemMatchesTheTwin) {
  std::mt19937_64 rng(99);
  const double specials[] = {std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity(), -2e9, 1e9, 1e-7, 0};
  std::uniform_real_distribution<double> u(-3, 3);
  int problems = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    const int n = 1 + static_cast<int>(rng() % 4);
    Pose pose;
    pose.links.resize(n);
    double v[4][7];
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 7; ++k) v[i][k] = u(rng);
      for (int spoil = static_cast<int>(rng() % 2); spoil > 0; --spoil) {
        v[i][rng() % 7] = specials[rng() % std::size(specials)];
      }
      if (rng() % 8 == 0) v[i][3] = v[i][4] = v[i][5] = v[i][6] = 1e-8;
      pose.links[i].p = {v[i][0], v[i][1], v[i][2]};
      pose.links[i].q = Eigen::Quaterniond(v[i][3], v[i][4], v[i][5], v[i][6]);
    }
    // The twin: the first (link, kind, component) in the documented order.
    std::optional<PoseProblem> want;
    for (int i = 0; i < n && !want; ++i) {
      for (int k = 0; k < 7 && !want; ++k) {
        if (!std::isfinite(v[i][k])) {
          want = PoseProblem{PoseProblem::Kind::kNonFinite, i, k >= 3, k < 3 ? k : k - 3, v[i][k]};
        }
      }
      for (int k = 0; k < 3 && !want; ++k) {
        if (std::fabs(v[i][k]) > 1e9) {
          want = PoseProblem{PoseProblem::Kind::kPositionOutOfRange, i, false, k, v[i][k]};
        }
      }
      const double norm = std::sqrt(v[i][3] * v[i][3] + v[i][4] * v[i][4] + v[i][5] * v[i][5] +
                                    v[i][6] * v[i][6]);
      if (!want && !(norm >= 1e-6)) {
        want = PoseProblem{PoseProblem::Kind::kZeroQuaternion, i, false, -1, norm};
      }
    }
    const std::optional<PoseProblem> got = FindPoseProblem(pose, n);
    ASSERT_EQ(got.has_value(), want.has_value()) << "trial " << trial;
    Pose copy = pose;
    const std::string error = ValidateAndNormalizePose(&copy, n);
    EXPECT_EQ(error.empty(), !want.has_value());
    if (!want) continue;
    ++problems;
    EXPECT_EQ(got->kind, want->kind) << "trial " << trial;
    EXPECT_EQ(got->link, want->link);
    EXPECT_EQ(got->in_orientation, want->in_orientation);
    EXPECT_EQ(got->component, want->component);
    if (want->kind == PoseProblem::Kind::kZeroQuaternion) {
      EXPECT_NEAR(got->value, want->value, 1e-12);
    } else if (std::isnan(want->value)) {
      EXPECT_TRUE(std::isnan(got->value));
    } else {
      EXPECT_EQ(got->value, want->value);
    }
    EXPECT_EQ(error, got->Describe(n));
    EXPECT_EQ(error.rfind("link " + std::to_string(want->link) + ": ", 0), 0u) << error;
  }
  EXPECT_GT(problems, 1000);  // The spoils did reach every branch often.
}

TEST(FindPoseProblemTest, WrongLinkCountAndTheCliWording) {
  Pose pose;
  pose.links.resize(2);
  const std::optional<PoseProblem> count = FindPoseProblem(pose, 3);
  ASSERT_TRUE(count);
  EXPECT_EQ(count->kind, PoseProblem::Kind::kLinkCount);
  EXPECT_EQ(count->Describe(3), "expected 3 link poses, got 2");
  pose.links[1].q = Eigen::Quaterniond(0, 0, 0, 0);
  EXPECT_EQ(ValidateAndNormalizePose(&pose, 2), "link 1: quaternion norm 0.000000 is below 1e-6");
  pose.links[1].p.x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(ValidateAndNormalizePose(&pose, 2), "link 1: non-finite number");
  pose.links[1].p.x() = 1.5e9;
  EXPECT_EQ(ValidateAndNormalizePose(&pose, 2), "link 1: position beyond 1e9 m");
}

// SamePose decides whether a kept motion may stand for a pair's: equal
// only when every number is, one changed bit anywhere makes them differ.
TEST(PoseTest, SamePoseComparesEveryNumber) {
  Pose x;
  x.utime = 1000;
  x.links.resize(3);
  for (int i = 0; i < 3; ++i) {
    x.links[i].p = Eigen::Vector3d(0.1 * i, -0.2, 0.3);
    x.links[i].q = Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * i, Eigen::Vector3d::UnitZ()));
  }
  EXPECT_TRUE(SamePose(x, x));
  Pose y = x;
  y.utime += 1;
  EXPECT_FALSE(SamePose(x, y));
  y = x;
  y.links.pop_back();
  EXPECT_FALSE(SamePose(x, y));
  for (int i = 0; i < 3; ++i) {
    for (int c = 0; c < 7; ++c) {
      y = x;
      double& v = c < 3 ? y.links[i].p[c] : y.links[i].q.coeffs()[c - 3];
      v = std::nextafter(v, 2.0);
      EXPECT_FALSE(SamePose(x, y)) << "link " << i << " number " << c;
    }
  }
  y = x;
  x.links[0].p.x() = 0.0;
  y.links[0].p.x() = -0.0;
  EXPECT_FALSE(SamePose(x, y));  // Equal values, other bits: motions may differ in zeros.
}

}  // namespace
}  // namespace sweptccd
