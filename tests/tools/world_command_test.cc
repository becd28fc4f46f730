// `sweptccd world` (SPEC section 8, "Offline"), run as the real binary on
// files this test writes: a small world with analytic contact times (records
// per avatar in world-file order, `others` avatars then objects, windows that
// start mid-pair, an invalid record with "others": []), --per-link,
// --output, filters from either avatar, worlds with avatars only, objects
// only or an empty `env`, and refusals (exit 2, one line on stderr naming the
// file and the problem).

#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
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

constexpr char kBar[] =
    R"({"name": "bar", "links": [{"name": "bar", "parent": null, "a": [-0.5, 0, 0], "b": [0.5, 0, 0], "radius": 0.1}]})";

std::string Line(int64_t utime, double y) {
  return "{\"utime\": " + std::to_string(utime) + ", \"links\": [[0, " + std::to_string(y) +
         ", 0, 1, 0, 0, 0]]}\n";
}

class WorldCommandTest : public test::TempDirTest {
 protected:
  WorldCommandTest() : TempDirTest("world") {}

  void SetUp() override {
    TempDirTest::SetUp();
    Write("bar.json", kBar);
    // alice stays at the origin; line 1 is garbage (an invalid record).
    Write("alice.jsonl",
          Line(1'000'000, 0) + "garbage\n" + Line(1'010'000, 0) + Line(1'020'000, 0));
    // bob comes down from y = 1 to y = 0 over 20 ms: the bars touch at
    // y = 0.2, i.e. at t = 1'016'000.
    Write("bob.jsonl", Line(1'000'000, 1.0) + Line(1'020'000, 0.0));
    Write("cup.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n");
    // The cup appears mid-pair, far away, and stays.
    Write("cup.jsonl",
          "{\"utime\": 1015000, \"pose\": [5, 0, 0, 1, 0, 0, 0]}\n"
          "{\"utime\": 1030000, \"pose\": [5, 0, 0, 1, 0, 0, 0]}\n");
    Write("floor.obj", "v -9 -1 -9\nv 9 -1 -9\nv 9 -1 9\nv -9 -1 9\nf 1 2 3 4\n");
  }

  RunResult Run(const std::vector<std::string>& args) {
    return testing::RunBinary(kBinary, args, Path("out.txt"), Path("err.txt"), 120);
  }

  std::vector<json> Records(const std::string& text) {
    std::vector<json> out;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
      if (!line.empty()) out.push_back(json::parse(line));
    }
    return out;
  }

  std::string World(const std::string& alice_ignore = "[]", bool objects = true, bool env = true) {
    std::string w = R"({"avatars": [
      {"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl", "ignore": )" +
                    alice_ignore + R"(},
      {"id": "bob", "skeleton": "bar.json", "poses": "bob.jsonl", "motion": "independent"}])";
    if (objects) w += R"(, "objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}])";
    w += env ? R"(, "env": ["floor.obj"]})" : R"(, "env": []})";
    return Write("world.json", w);
  }
};

const json* Other(const json& record, const std::string& id) {
  for (const json& e : record["others"]) {
    if (e["entity"] == id) return &e;
  }
  return nullptr;
}

TEST_F(WorldCommandTest, AnswersEveryAvatarPairWithOthers) {
  const RunResult r = Run({"world", "--world", World(), "--backend", "cpu"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::vector<json> recs = Records(r.out);
  ASSERT_EQ(recs.size(), 4u) << r.out;  // alice: 3 records, bob: 1.
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(recs[i]["avatar"], "alice");
    EXPECT_EQ(recs[i]["pair"], i);
  }
  EXPECT_EQ(recs[3]["avatar"], "bob");
  // The garbage line: invalid, no others.
  EXPECT_EQ(recs[0]["result"], "invalid");
  EXPECT_EQ(recs[0]["others"], json::array());
  // alice [1.00 s, 1.01 s]: bob far (y >= 0.5), the cup not there yet.
  EXPECT_EQ(recs[1]["result"], "free");
  ASSERT_EQ(recs[1]["others"].size(), 1u);
  EXPECT_EQ(recs[1]["others"][0]["entity"], "bob");
  EXPECT_EQ(recs[1]["others"][0]["result"], "free");
  // alice [1.01 s, 1.02 s]: bob touches at 1'016'000; the cup's window
  // starts mid-pair.
  const json& rec = recs[2];
  EXPECT_EQ(rec["result"], "free");  // The floor is 0.9 m below.
  ASSERT_EQ(rec["others"].size(), 2u);
  EXPECT_EQ(rec["others"][0]["entity"], "bob");
  EXPECT_EQ(rec["others"][1]["entity"], "cup");
  const json& bob = rec["others"][0];
  EXPECT_EQ(bob["kind"], "avatar");
  EXPECT_EQ(bob["window"], json::array({1'010'000, 1'020'000}));
  ASSERT_EQ(bob["result"], "contact");
  EXPECT_FALSE(bob["initially_colliding"].get<bool>());
  EXPECT_LE(bob["t_lo"].get<double>(), 1'016'000.0);
  EXPECT_GE(bob["t_hi"].get<double>(), 1'016'000.0 - 20);  // within delta = 1 mm (20 us)
  EXPECT_LE(bob["t_hi"].get<double>() - bob["t_lo"].get<double>(), 100.0);
  EXPECT_NEAR(bob["s_lo"].get<double>(), (bob["t_lo"].get<double>() - 1'010'000) / 10'000, 1e-9);
  ASSERT_GE(bob["contacts"].size(), 1u);
  const json& c = bob["contacts"][0];
  EXPECT_EQ(c["link"], 0);
  EXPECT_EQ(c["other_link"], 0);
  EXPECT_NEAR(c["normal"][1].get<double>(), -1.0, 1e-9);  // From bob (above) towards alice.
  EXPECT_LE(c["separation"].get<double>(), 1e-3);
  const json& cup = rec["others"][1];
  EXPECT_EQ(cup["kind"], "object");
  EXPECT_EQ(cup["window"], json::array({1'015'000, 1'020'000}));
  EXPECT_EQ(cup["result"], "free");
  // bob's record sees alice (both halves of her stream) and the cup.
  const json* alice = Other(recs[3], "alice");
  ASSERT_NE(alice, nullptr);
  EXPECT_EQ((*alice)["window"], json::array({1'000'000, 1'020'000}));
  EXPECT_EQ((*alice)["result"], "contact");
  EXPECT_LE((*alice)["t_lo"].get<double>(), 1'016'000.0);
  EXPECT_NEAR((*alice)["contacts"][0]["normal"][1].get<double>(), 1.0, 1e-9);
  EXPECT_NE(Other(recs[3], "cup"), nullptr);
}

TEST_F(WorldCommandTest, PerLinkAndOutputFile) {
  const RunResult r = Run(
      {"world", "--world", World(), "--per-link", "--output", Path("res.jsonl"), "--eps", "1e-3"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  EXPECT_TRUE(r.out.empty());
  const std::vector<json> recs = Records(testing::ReadFile(Path("res.jsonl")));
  ASSERT_EQ(recs.size(), 4u);
  const json& bob = recs[2]["others"][0];
  ASSERT_EQ(bob["links"].size(), 1u);
  EXPECT_EQ(bob["links"][0]["link"], 0);
  EXPECT_LE(bob["links"][0]["t_hi"].get<double>() - bob["links"][0]["t_lo"].get<double>(), 1000.0);
}

TEST_F(WorldCommandTest, FilterOfEitherAvatarAppliesToBoth) {
  const RunResult r =
      Run({"world", "--world", World(R"([{"link": "bar", "entity": "bob", "other_link": 0}])")});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::vector<json> recs = Records(r.out);
  ASSERT_EQ(recs.size(), 4u);
  EXPECT_EQ(Other(recs[2], "bob")->at("result"), "free");
  EXPECT_EQ(Other(recs[3], "alice")->at("result"), "free");
}

TEST_F(WorldCommandTest, AvatarsOnlyObjectsOnlyAndNoEnvironment) {
  {
    const RunResult r = Run({"world", "--world", World("[]", /*objects=*/false, /*env=*/false)});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    const std::vector<json> recs = Records(r.out);
    ASSERT_EQ(recs.size(), 4u);
    EXPECT_EQ(recs[2]["result"], "free");
    EXPECT_EQ(recs[2]["others"].size(), 1u);
  }
  {
    Write("objects.json",
          R"({"objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}]})");
    const RunResult r = Run({"world", "--world", Path("objects.json")});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    EXPECT_TRUE(r.out.empty());
  }
}

// A thin plate thrown down through alice's bar at 200 m/s: its triangle
// reaches the bar's surface (y = 0.1) at t = 1'014'500.
TEST_F(WorldCommandTest, ThinObjectThrownThroughALimb) {
  Write("plate.obj", "v -0.05 0 -0.05\nv 0.05 0 -0.05\nv 0 0 0.05\nf 1 2 3\n");
  Write("plate.jsonl",
        "{\"utime\": 1010000, \"pose\": [0, 1, 0, 1, 0, 0, 0]}\n"
        "not json\n"
        "{\"utime\": 1020000, \"pose\": [0, -1, 0, 0, 0, 1, 0]}\n");  // Half a turn about y.
  const std::string world = Write("plate_world.json", R"({"avatars": [
      {"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl"}],
      "objects": [{"id": "plate", "mesh": "plate.obj", "poses": "plate.jsonl"}]})");
  const RunResult r = Run({"world", "--world", world});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::vector<json> recs = Records(r.out);
  ASSERT_EQ(recs.size(), 3u);
  // [1.00 s, 1.01 s] ends as the plate appears: a zero-length window.
  ASSERT_EQ(recs[1]["others"].size(), 1u);
  EXPECT_EQ(recs[1]["others"][0]["window"], json::array({1'010'000, 1'010'000}));
  EXPECT_EQ(recs[1]["others"][0]["result"], "free");
  ASSERT_EQ(recs[2]["others"].size(), 1u);
  const json& e = recs[2]["others"][0];
  EXPECT_EQ(e["kind"], "object");
  ASSERT_EQ(e["result"], "contact");
  EXPECT_LE(e["t_lo"].get<double>(), 1'014'500.0);
  EXPECT_GE(e["t_hi"].get<double>(), 1'014'500.0 - 5);  // delta = 1 mm is 5 us here.
  const json& c = e["contacts"][0];
  EXPECT_EQ(c["triangle"], 0);
  EXPECT_FALSE(c.contains("other_link"));
  EXPECT_NEAR(c["normal"][1].get<double>(), -1.0, 1e-6);  // From the plate down to the bar.
  EXPECT_LE(c["separation"].get<double>(), 1e-3);
  EXPECT_NEAR(c["point_link"][1].get<double>(), 0.0, 1e-9);

  // Lines that are not used: one of 100 KB, one whose valid JSON is
  // followed by a NUL and more bytes (it would put the plate at y = 5); the
  // last line has no newline. The answer is the same.
  Write("plate.jsonl",
        "{\"utime\": 1010000, \"pose\": [0, 1, 0, 1, 0, 0, 0]}\n" + std::string(100'000, '[') +
            "\n" + std::string("{\"utime\": 1015000, \"pose\": [0, 5, 0, 1, 0, 0, 0]}\0x\n", 52) +
            "{\"utime\": 1020000, \"pose\": [0, -1, 0, 0, 0, 1, 0]}");
  const RunResult r3 = Run({"world", "--world", world});
  ASSERT_TRUE(r3.exited && r3.code == 0) << r3.Describe();
  const std::vector<json> recs3 = Records(r3.out);
  ASSERT_EQ(recs3.size(), 3u);
  EXPECT_EQ(recs3[2]["others"][0], recs[2]["others"][0]);
  ASSERT_EQ(recs3[2]["others"][0]["window"], json::array({1'010'000, 1'020'000}));

  // A {"link", "entity"} rule naming the object silences it.
  const std::string ignoring = Write("plate_world.json", R"({"avatars": [
      {"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl",
       "ignore": [{"link": "*", "entity": "plate"}, {"link": 0, "entity": "nobody"}]}],
      "objects": [{"id": "plate", "mesh": "plate.obj", "poses": "plate.jsonl"}]})");
  const RunResult r2 = Run({"world", "--world", ignoring});
  ASSERT_TRUE(r2.exited && r2.code == 0) << r2.Describe();
  const std::vector<json> recs2 = Records(r2.out);
  ASSERT_EQ(recs2.size(), 3u);
  EXPECT_EQ(recs2[2]["others"][0]["result"], "free");
}

// The static-environment part moves each avatar by its own motion model and
// equals `sweptccd query` with that model: a two-link arm swings 90 degrees;
// articulated, its tip sweeps out to x + y = 2.83 and meets a wall at
// x + y = 2.7; independent, it stays below 2.42 and is free.
TEST_F(WorldCommandTest, EnvironmentPartUsesEachAvatarsMotionModel) {
  Write("arm.json", R"({"name": "arm", "links": [
      {"name": "upper", "parent": null, "a": [0, 0, 0], "b": [1, 0, 0], "radius": 0.05},
      {"name": "lower", "parent": "upper", "a": [0, 0, 0], "b": [1, 0, 0], "radius": 0.05}]})");
  Write("arm.jsonl",
        "{\"utime\": 0, \"links\": [[0, 0, 0, 1, 0, 0, 0], [1, 0, 0, 1, 0, 0, 0]]}\n"
        "{\"utime\": 100000, \"links\": [[0, 0, 0, 0.7071067811865476, 0, 0, 0.7071067811865476],"
        " [0, 1, 0, 0.7071067811865476, 0, 0, 0.7071067811865476]]}\n");
  Write("wall.obj", "v 2.7 0 -5\nv 0 2.7 -5\nv 1.35 1.35 5\nf 1 2 3\n");
  for (const std::string motion : {"articulated", "independent"}) {
    SCOPED_TRACE(motion);
    const std::string world = Write("arm_world.json", R"({"avatars": [{"id": "arm",
        "skeleton": "arm.json", "poses": "arm.jsonl", "motion": ")" +
                                                          motion + R"("}],
        "env": ["wall.obj"]})");
    const RunResult w = Run({"world", "--world", world});
    ASSERT_TRUE(w.exited && w.code == 0) << w.Describe();
    const RunResult q = Run({"query", "--skeleton", Path("arm.json"), "--poses", Path("arm.jsonl"),
                             "--env", Path("wall.obj"), "--motion", motion});
    ASSERT_TRUE(q.exited && q.code == 0) << q.Describe();
    std::vector<json> a = Records(w.out), b = Records(q.out);
    ASSERT_EQ(a.size(), 1u);
    ASSERT_EQ(b.size(), 1u);
    EXPECT_EQ(a[0]["result"], motion == "articulated" ? "contact" : "free");
    for (json* r : {&a[0], &b[0]}) {
      r->erase("elapsed_us");
      r->erase("stats");
      r->erase("avatar");
      r->erase("others");
    }
    EXPECT_EQ(a[0], b[0]);
  }
}

// --bench: the same work, a table of counts instead of the records (the
// timings are printed, never asserted).
// Past the work limit, every contact still has a witness (SPEC 8: at least
// one), also against an object whose only triangle is 2e12 m away (found by
// a review: the witness search stopped at 1e12 m).
TEST_F(WorldCommandTest, UndecidedEntriesCarryAWitness) {
  Write("far.obj", "v 2e12 0 0\nv 2e12 1 0\nv 2e12 0 1\nf 1 2 3\n");
  // Samples inside each pair: two pieces, so two items, past a limit of 1.
  Write("far.jsonl",
        "{\"utime\": 1000000, \"pose\": [0, 0, 0, 1, 0, 0, 0]}\n"
        "{\"utime\": 1005000, \"pose\": [0, 0, 0, 1, 0, 0, 0]}\n"
        "{\"utime\": 1015000, \"pose\": [0, 0, 0, 1, 0, 0, 0]}\n"
        "{\"utime\": 1020000, \"pose\": [0, 0, 0, 1, 0, 0, 0]}\n");
  const std::string world = Write("far_world.json", R"({"avatars": [
      {"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl"},
      {"id": "bob", "skeleton": "bar.json", "poses": "bob.jsonl"}],
    "objects": [{"id": "far", "mesh": "far.obj", "poses": "far.jsonl"}]})");
  for (const char* per_link : {"", "--per-link"}) {
    std::vector<std::string> args = {"world", "--world",         world, "--backend",
                                     "cpu",   "--max-intervals", "1"};
    if (*per_link) args.push_back(per_link);
    const RunResult r = Run(args);
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    int undecided = 0;
    for (const json& rec : Records(r.out)) {
      for (const json& e : rec["others"]) {
        if (e["result"] != "contact") continue;
        EXPECT_GE(e["contacts"].size(), 1u) << e.dump();
        undecided += e["undecided"].get<bool>();
        for (const json& l : e.value("links", json::array())) {
          EXPECT_TRUE(l.contains("contact")) << l.dump();
        }
      }
    }
    // bob's pair against alice, and all three pairs against the far object.
    EXPECT_GE(undecided, 4) << per_link << "\n" << r.out;
  }
}

TEST_F(WorldCommandTest, BenchPrintsATable) {
  const RunResult r = Run({"world", "--world", World(), "--bench"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  EXPECT_NE(r.out.find("avatars 2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("objects 1\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("records 4\n"), std::string::npos) << r.out;
  // Entries: alice 1 + 2 (2 valid records), bob 2; contacts: bob both ways.
  EXPECT_NE(r.out.find("entity_entries 5\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("entity_contacts 2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("record_us_p99 "), std::string::npos) << r.out;
}

// Seeded random corruptions of the world file and of the object pose file:
// never a crash or a hang; exit 0 (with JSON lines) or 2 (one line on
// stderr).
TEST_F(WorldCommandTest, CorruptedInputsNeverCrash) {
  const std::string world_text = testing::ReadFile(World());
  const std::string cup_text = testing::ReadFile(Path("cup.jsonl"));
  std::mt19937_64 rng(20261124);
  const std::string alphabet = "{}[]\",:0123456789.-eE \n*abnrtu\xff";
  for (int trial = 0; trial < 24; ++trial) {
    SCOPED_TRACE(trial);
    std::string w = world_text, c = cup_text;
    std::string* target = trial % 2 == 0 ? &w : &c;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < edits && !target->empty(); ++k) {
      const size_t at = rng() % target->size();
      switch (rng() % 3) {
        case 0:
          (*target)[at] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          target->erase(at, 1 + rng() % 8);
          break;
        default:
          target->insert(at, 1, alphabet[rng() % alphabet.size()]);
          break;
      }
    }
    Write("world.json", w);
    Write("cup.jsonl", c);
    const RunResult r = Run({"world", "--world", Path("world.json")});
    ASSERT_TRUE(r.exited) << r.Describe();
    ASSERT_TRUE(r.code == 0 || r.code == 2) << r.Describe();
    if (r.code == 2) {
      EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
      EXPECT_TRUE(r.out.empty());
    } else {
      for (const json& rec : Records(r.out)) EXPECT_TRUE(rec.contains("others"));
    }
  }
}

// The static environment on the GPU (llvmpipe here, never skipped: the test
// fails when the GPU was not chosen), the entities on the CPU: the same
// records as --backend cpu, timings and work counters aside.
TEST_F(WorldCommandTest, GpuAndCpuBackendsGiveTheSameRecords) {
  Write("floor.obj", "v -9 -0.05 -9\nv 9 -0.05 -9\nv 9 -0.05 9\nv -9 -0.05 9\nf 1 2 3 4\n");
  const std::string world = World();
  const RunResult cpu = Run({"world", "--world", world, "--backend", "cpu", "--per-link"});
  ASSERT_TRUE(cpu.exited && cpu.code == 0) << cpu.Describe();
  const RunResult gpu = Run({"world", "--world", world, "--backend", "gpu", "--per-link"});
  ASSERT_TRUE(gpu.exited && gpu.code == 0) << gpu.Describe();
  EXPECT_NE(gpu.err.find("backend gpu"), std::string::npos) << gpu.err;
  std::vector<json> a = Records(cpu.out), b = Records(gpu.out);
  ASSERT_EQ(a.size(), 4u);
  ASSERT_EQ(a.size(), b.size());
  int env_contacts = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    for (json* r : {&a[i], &b[i]}) {
      r->erase("elapsed_us");
      r->erase("stats");
    }
    env_contacts += a[i]["result"] == "contact";
    EXPECT_EQ(a[i], b[i]) << "record " << i;
  }
  EXPECT_GE(env_contacts, 2);  // alice lies on the floor.
  // auto (issue 11): calibrated with the first avatar on this scene, both
  // figures on stderr, the same records whichever it kept.
  const RunResult automatic =
      Run({"world", "--world", world, "--backend", "auto", "--per-link", "--threads", "1"});
  ASSERT_TRUE(automatic.exited && automatic.code == 0) << automatic.Describe();
  EXPECT_TRUE(std::regex_search(
      automatic.err, std::regex("sweptccd world: backend (cpu|gpu) \\(auto: cpu [0-9]+ us, gpu "
                                "[0-9]+ us per pair, medians of [1-9][0-9]* timed pairs each; ")))
      << automatic.err;
  std::vector<json> c = Records(automatic.out);
  ASSERT_EQ(c.size(), a.size());
  for (size_t i = 0; i < c.size(); ++i) {
    c[i].erase("elapsed_us");
    c[i].erase("stats");
    EXPECT_EQ(a[i], c[i]) << "record " << i;
  }
}

// The flags `world` shares with `query` (tools/command_common.h): an output
// that names the world file or any file it names is refused before
// anything is written (the input intact), --max-links bounds every skeleton,
// --gpu-device picks the EGL device (a missing one: the CPU answers, and
// says why).
TEST_F(WorldCommandTest, SharesQuerysOutputCheckLinkLimitAndGpuDevice) {
  const std::string world = World();
  const std::string world_text = testing::ReadFile(world);
  const std::string bob = testing::ReadFile(Path("bob.jsonl"));
  struct Clash {
    std::string output, role;
  };
  const std::vector<Clash> clashes = {
      {world, "--world input"},
      {Path("bob.jsonl"), "--world's avatars[1] ('bob') poses input"},
      {Path("./bar.json"), "--world's avatars[0] ('alice') skeleton input"},
      {Path("cup.obj"), "--world's objects[0] ('cup') mesh input"},
      {Path("floor.obj"), "--world's env[0] input"},
  };
  for (const Clash& c : clashes) {
    SCOPED_TRACE(c.output);
    const RunResult r = Run({"world", "--world", world, "--backend", "cpu", "--output", c.output});
    ASSERT_TRUE(r.exited) << r.Describe();
    EXPECT_EQ(r.code, 2) << r.Describe();
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_NE(r.err.find("--output " + c.output + " is also the " + c.role), std::string::npos)
        << r.err;
  }
  EXPECT_EQ(testing::ReadFile(world), world_text);
  EXPECT_EQ(testing::ReadFile(Path("bob.jsonl")), bob);

  Write("two.json", R"({"name": "two", "links": [
    {"name": "a", "parent": null, "a": [0, 0, 0], "b": [0.1, 0, 0], "radius": 0.1},
    {"name": "b", "parent": "a", "a": [0, 0, 0], "b": [0.1, 0, 0], "radius": 0.1}]})");
  Write("two.jsonl",
        "{\"utime\": 1000000, \"links\": [[0, 0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0, 0]]}\n");
  const std::string two =
      Write("two_world.json",
            R"({"avatars": [{"id": "t", "skeleton": "two.json", "poses": "two.jsonl"}]})");
  const RunResult over = Run({"world", "--world", two, "--max-links", "1"});
  ASSERT_TRUE(over.exited) << over.Describe();
  EXPECT_EQ(over.code, 2) << over.Describe();
  EXPECT_NE(over.err.find("2 links, above the limit of 1"), std::string::npos) << over.err;
  EXPECT_NE(over.err.find("--max-links"), std::string::npos) << over.err;
  const RunResult enough = Run({"world", "--world", two, "--max-links", "2", "--backend", "cpu"});
  ASSERT_TRUE(enough.exited && enough.code == 0) << enough.Describe();
  const RunResult zero = Run({"world", "--world", two, "--max-links", "0"});
  ASSERT_TRUE(zero.exited) << zero.Describe();
  EXPECT_EQ(zero.code, 2) << zero.Describe();
  EXPECT_NE(zero.err.find("--max-links"), std::string::npos) << zero.err;

  const RunResult cpu = Run({"world", "--world", world, "--backend", "cpu"});
  ASSERT_TRUE(cpu.exited && cpu.code == 0) << cpu.Describe();
  const RunResult missing =
      Run({"world", "--world", world, "--backend", "gpu", "--gpu-device", "31"});
  ASSERT_TRUE(missing.exited && missing.code == 0) << missing.Describe();
  EXPECT_NE(missing.err.find("EGL device 31 does not exist"), std::string::npos) << missing.err;
  EXPECT_NE(missing.err.find("backend cpu (gpu requested but unavailable"), std::string::npos)
      << missing.err;
  std::vector<json> a = Records(cpu.out), b = Records(missing.out);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    for (json* r : {&a[i], &b[i]}) {
      r->erase("elapsed_us");
      r->erase("stats");
    }
    EXPECT_EQ(a[i], b[i]) << "record " << i;
  }
}

TEST_F(WorldCommandTest, RefusesBadWorldsWithOneLine) {
  struct Case {
    std::string name, text, expect;
  };
  const std::vector<Case> cases = {
      {"duplicate id",
       R"({"avatars": [{"id": "x", "skeleton": "bar.json", "poses": "alice.jsonl"}],
           "objects": [{"id": "x", "mesh": "cup.obj", "poses": "cup.jsonl"}]})",
       "duplicate id 'x'"},
      {"malformed id",
       R"({"avatars": [{"id": "bad id!", "skeleton": "bar.json", "poses": "alice.jsonl"}]})",
       "malformed id 'bad id!'"},
      // Found by a review: the raw newline split the refusal over two lines.
      {"id with a newline and an escape",
       R"({"objects": [{"id": "O\n\u001b[2J", "mesh": "cup.obj", "poses": "cup.jsonl"}]})",
       "malformed id 'O\\n\\x1b[2J'"},
      {"link name with a newline",
       R"({"avatars": [{"id": "a", "skeleton": "bar.json", "poses": "alice.jsonl",
                        "ignore": [{"link": "no\nsuch", "entity": "b"}]}]})",
       "unknown link 'no\\nsuch'"},
      {"too long id",
       R"({"avatars": [{"id": ")" + std::string(65, 'a') +
           R"(", "skeleton": "bar.json", "poses": "alice.jsonl"}]})",
       "malformed id"},
      {"missing mesh", R"({"objects": [{"id": "cup", "mesh": "nope.obj", "poses": "cup.jsonl"}]})",
       "nope.obj"},
      {"unknown link",
       R"({"avatars": [{"id": "a", "skeleton": "bar.json", "poses": "alice.jsonl",
                        "ignore": [{"link": "nosuch", "entity": "b"}]}]})",
       "unknown link 'nosuch'"},
      {"unknown other link",
       R"({"avatars": [{"id": "a", "skeleton": "bar.json", "poses": "alice.jsonl",
                        "ignore": [{"link": "*", "entity": "b", "other_link": "elbow"}]},
                       {"id": "b", "skeleton": "bar.json", "poses": "bob.jsonl"}]})",
       "unknown link 'elbow'"},
      // Found by fuzz_world: "" names the world's folder, which opens but
      // cannot be read (it ended the process).
      {"avatar poses a folder",
       R"({"avatars": [{"id": "a", "skeleton": "bar.json", "poses": ""}]})",
       "is a folder, where the pose stream file should be"},
      {"object poses a folder", R"({"objects": [{"id": "cup", "mesh": "cup.obj", "poses": ""}]})",
       "is a folder, where the object pose file should be"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = Write("bad.json", c.text);
    const RunResult r = Run({"world", "--world", path});
    ASSERT_TRUE(r.exited) << r.Describe();
    EXPECT_EQ(r.code, 2) << r.Describe();
    EXPECT_TRUE(r.out.empty());
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
    if (c.name.find("a folder") != std::string::npos) {
      const std::string folder = std::filesystem::path(path).parent_path().string();
      EXPECT_NE(r.err.find(folder), std::string::npos) << r.err;  // The path, resolved.
    } else if (c.name != "missing mesh") {
      EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
    }
  }
}

}  // namespace
}  // namespace sweptccd
