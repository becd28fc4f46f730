// `sweptccd world-bench` at a tiny size (3 avatars, 2 objects, half a
// second), run as the real binary: the world it writes (ids, rates, the
// holder's ignore rules, a held object sampled at its holder's utimes, a
// thrown one), `sweptccd world` reads that world, and the table has its rows,
// counts that agree with the written streams and a met/missed line per
// target. Counts and structure only: times are never asserted.

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/common/temp_dir_test.h"
#include "tests/tools/run_binary.h"

namespace sweptccd {
namespace {

using nlohmann::json;
using testing::RunResult;

const std::string kBinary = SWEPTCCD_BINARY;

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

// The first number after `prefix` at the start of a line of `text`.
double Field(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) == 0) return std::stod(line.substr(prefix.size()));
  }
  ADD_FAILURE() << "no line starting with " << prefix << " in\n" << text;
  return -1;
}

class WorldBenchCommandTest : public test::TempDirTest {
 protected:
  WorldBenchCommandTest() : TempDirTest("world_bench") {}
  RunResult Run(const std::vector<std::string>& args) {
    return testing::RunBinary(kBinary, args, Path("out.txt"), Path("err.txt"), 300);
  }
};

TEST_F(WorldBenchCommandTest, WritesTheWorldAndPrintsTheTable) {
  const RunResult r = Run({"world-bench", "--out", Path("w"), "--avatars", "3", "--objects", "2",
                           "--seconds", "0.5", "--warmup", "2"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();

  const json world = json::parse(std::ifstream(Path("w/world.json")));
  ASSERT_EQ(world["avatars"].size(), 3u);
  ASSERT_EQ(world["objects"].size(), 2u);
  EXPECT_EQ(world["objects"][0]["id"], "held0");
  EXPECT_EQ(world["objects"][1]["id"], "thrown");
  ASSERT_EQ(world["env"].size(), 1u);
  // Avatar 2 holds held0 in its right hand: hand and forearm ignore it.
  EXPECT_EQ(world["avatars"][2]["ignore"], json::parse(R"([{"link": "hand_r", "entity": "held0"},
                            {"link": "forearm_r", "entity": "held0"}])"));
  EXPECT_TRUE(world["avatars"][0]["ignore"].empty());

  // Rates 90, 72, 60 Hz over 0.5 s; the held object has its holder's utimes.
  int64_t records = 0;
  const size_t expected_poses[3] = {46, 37, 31};
  std::vector<std::vector<std::string>> streams;
  for (int k = 0; k < 3; ++k) {
    streams.push_back(Lines(Path("w/avatar" + std::to_string(k) + ".jsonl")));
    EXPECT_EQ(streams[k].size(), expected_poses[k]) << k;
    records += static_cast<int64_t>(streams[k].size()) - 1;
  }
  const std::vector<std::string> held = Lines(Path("w/held0.jsonl"));
  ASSERT_EQ(held.size(), streams[2].size());
  for (size_t i = 0; i < held.size(); ++i) {
    EXPECT_EQ(json::parse(held[i])["utime"], json::parse(streams[2][i])["utime"]) << i;
  }
  const std::vector<std::string> thrown = Lines(Path("w/thrown.jsonl"));
  ASSERT_GE(thrown.size(), 30u);  // 120 Hz over 0.3 s at least.
  // Thrown from 30% of the clip: it exists only for its flight.
  EXPECT_EQ(json::parse(thrown.front())["utime"], 1'150'000);

  // The table: both rows over every record, the ratio lines, the counts.
  const std::string& out = r.out;
  EXPECT_EQ(Field(out, "| env-only | "), records) << out;
  EXPECT_EQ(Field(out, "| whole | "), records) << out;
  for (const char* target : {"whole median / env-only median: ", "whole p99 / whole median: "}) {
    EXPECT_TRUE(std::regex_search(
        out, std::regex(std::string(target) + "[0-9.]+ \\(target <= [25]\\): (met|missed)")))
        << target << "\n"
        << out;
  }
  EXPECT_TRUE(std::regex_search(out, std::regex("avatar pairs with a shared contact: [0-3] of 3 ")))
      << out;
  const double entries = Field(out, "entity entries: ");
  // Every other avatar overlaps every record (all streams cover the same
  // half second, a millisecond apart at most); objects only where they exist.
  EXPECT_GE(entries, 2.0 * records - 6) << out;
  EXPECT_LE(entries, 4.0 * records) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex("entity contacts: avatar [0-9]+, held object "
                                                "[0-9]+, thrown object [0-9]+")))
      << out;

  // The written world is a valid SPEC 8 world: one record per avatar pair.
  const RunResult q = Run({"world", "--world", Path("w/world.json"), "--backend", "cpu"});
  ASSERT_TRUE(q.exited && q.code == 0) << q.Describe();
  EXPECT_EQ(std::count(q.out.begin(), q.out.end(), '\n'), records);
}

// --threads N (issue 30): the records are answered by N workers, and what
// the table counts (records per kind, contacts, entries, avatar pairs) is
// the same as with one; only the times may differ.
std::vector<std::string> Counts(const std::string& out) {
  std::vector<std::string> counts;
  std::istringstream in(out);
  std::string line;
  const std::regex row("\\| ([^|]+) \\| ([0-9]+) \\| .*");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_match(line, m, row)) counts.push_back(m[1].str() + ": " + m[2].str());
    for (const char* prefix : {"avatar pairs with", "records with", "entity "}) {
      if (line.rfind(prefix, 0) == 0) counts.push_back(line);
    }
  }
  return counts;
}

TEST_F(WorldBenchCommandTest, CountsAreTheSameForAnyNumberOfThreads) {
  const std::vector<std::string> args = {"world-bench", "--avatars", "4",        "--objects", "2",
                                         "--seconds",   "1",         "--warmup", "2"};
  std::vector<std::string> one = args, three = args;
  one.insert(one.end(), {"--out", Path("w1"), "--threads", "1"});
  three.insert(three.end(), {"--out", Path("w3"), "--threads", "3"});
  const RunResult a = Run(one);
  ASSERT_TRUE(a.exited && a.code == 0) << a.Describe();
  const std::string out1 = a.out;
  const RunResult b = Run(three);
  ASSERT_TRUE(b.exited && b.code == 0) << b.Describe();
  EXPECT_NE(out1.find(", 1 worker, "), std::string::npos) << out1;
  EXPECT_NE(b.out.find(", 3 workers, "), std::string::npos) << b.out;
  const std::vector<std::string> c1 = Counts(out1), c3 = Counts(b.out);
  EXPECT_EQ(c1.size(), 16u) << out1;  // 11 table rows and 5 tally lines.
  EXPECT_EQ(c1, c3);
  // Not a vacuous comparison: the world has shared contacts.
  EXPECT_EQ(out1.find("records with a shared contact: 0 of"), std::string::npos) << out1;
}

// --scenario hands (issue 31): every avatar reaches for, grasps and carries
// its own box, as a 16-link and as an 81-link (meta-full-body, procedural
// fingers) avatar. The bench's tallies of what its answers found equal what
// `sweptccd world` answers on the two worlds it wrote (entry by entry
// counted from the records), the boxes are touched (by finger links for the
// 81-link avatars), and the table has a row per part and avatar size over
// every valid record.
struct HandsTally {
  int64_t records = 0, own_entries = 0, own_contacts = 0, own_initially = 0, own_undecided = 0;
  int64_t other_objects = 0, avatars = 0, entries = 0;
  std::string Describe() const {
    std::ostringstream os;
    os << "records " << records << " own " << own_entries << "/" << own_contacts << "/"
       << own_initially << "/" << own_undecided << " other objects " << other_objects << " avatars "
       << avatars << " entries " << entries;
    return os.str();
  }
};

TEST_F(WorldBenchCommandTest, HandsScenarioMatchesTheWorldCommand) {
  const RunResult r = Run({"world-bench", "--scenario", "hands", "--out", Path("h"), "--avatars",
                           "2", "--seconds", "1.5", "--warmup", "1", "--seed", "7"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::string& out = r.out;
  EXPECT_NE(out.find("PROCEDURALLY ANIMATED"), std::string::npos) << out;
  for (const char* links : {"16", "81"}) {
    SCOPED_TRACE(std::string(links) + " links");
    const json world = json::parse(std::ifstream(Path(std::string("h/world") + links + ".json")));
    ASSERT_EQ(world["avatars"].size(), 2u);
    ASSERT_EQ(world["objects"].size(), 2u);
    EXPECT_FALSE(world["avatars"][0].contains("ignore"));  // No rules: the grasp is answered.
    const json skeleton =
        json::parse(std::ifstream(Path(std::string("h/avatar0_") + links + ".json")));
    ASSERT_EQ(skeleton["links"].size(), std::string(links) == "16" ? 16u : 81u);

    // The world command's records, counted as the bench counts its answers.
    const RunResult q = Run(
        {"world", "--world", Path(std::string("h/world") + links + ".json"), "--backend", "cpu"});
    ASSERT_TRUE(q.exited && q.code == 0) << q.Describe();
    HandsTally want;
    int64_t finger_witnesses = 0;
    std::istringstream lines(q.out);
    std::string line;
    while (std::getline(lines, line)) {
      if (line.empty()) continue;
      const json rec = json::parse(line);
      if (rec["result"] == "invalid") continue;
      ++want.records;
      const std::string avatar = rec["avatar"];
      const std::string own = "object" + avatar.substr(std::string("avatar").size());
      for (const json& e : rec["others"]) {
        ++want.entries;
        const bool contact = e["result"] == "contact";
        if (e["entity"] == own) {
          ++want.own_entries;
          want.own_contacts += contact;
          want.own_initially += contact && e["initially_colliding"].get<bool>();
          want.own_undecided += contact && e["undecided"].get<bool>();
          if (!contact || avatar != "avatar0") continue;
          for (const json& c : e["contacts"]) {
            const std::string name = skeleton["links"][c["link"].get<int>()]["name"];
            finger_witnesses += name.find("HAND_") != std::string::npos;
          }
        } else if (e["kind"] == "object") {
          want.other_objects += contact;
        } else {
          want.avatars += contact;
        }
      }
    }
    // The bench's line for this size.
    const std::regex tally_re(std::string("links ") + links +
                              ": own-object entries ([0-9]+): contact ([0-9]+) \\(initially "
                              "colliding ([0-9]+), undecided ([0-9]+)\\); other objects: contact "
                              "([0-9]+); avatars: contact ([0-9]+); entity entries ([0-9]+) ");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(out, m, tally_re)) << out;
    HandsTally got;
    got.records =
        static_cast<int64_t>(Field(out, std::string("| ") + links + " | whole record | "));
    got.own_entries = std::stoll(m[1]);
    got.own_contacts = std::stoll(m[2]);
    got.own_initially = std::stoll(m[3]);
    got.own_undecided = std::stoll(m[4]);
    got.other_objects = std::stoll(m[5]);
    got.avatars = std::stoll(m[6]);
    got.entries = std::stoll(m[7]);
    EXPECT_EQ(got.Describe(), want.Describe());
    EXPECT_EQ(Field(out, std::string("| ") + links + " | env-only | "), want.records);
    EXPECT_EQ(Field(out, std::string("| ") + links +
                             " | own object (reach, grasp, carry, "
                             "release) | "),
              want.records);
    // The scenario does what it says: each avatar's hand meets its box,
    // the full body's fingers among its links.
    EXPECT_GT(want.own_contacts, 0);
    EXPECT_EQ(want.own_undecided, 0);
    if (std::string(links) == "81") {
      EXPECT_GT(finger_witnesses, 0);
    }
  }
}

TEST_F(WorldBenchCommandTest, RefusesBadSizes) {
  const RunResult r = Run({"world-bench", "--out", Path("w"), "--avatars", "1"});
  EXPECT_TRUE(r.exited && r.code == 2) << r.Describe();
  EXPECT_NE(r.err.find("--avatars >= 2"), std::string::npos) << r.err;
  const RunResult h =
      Run({"world-bench", "--out", Path("h"), "--scenario", "hands", "--threads", "2"});
  EXPECT_TRUE(h.exited && h.code == 2) << h.Describe();
  EXPECT_NE(h.err.find("--scenario hands runs on one thread"), std::string::npos) << h.err;
}

}  // namespace
}  // namespace sweptccd
