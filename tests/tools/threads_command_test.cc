// `--threads N` of `sweptccd query` and `sweptccd world` (issue 30): a batch
// of pairs answered by N workers gives the same records, byte for byte and in
// the same order, as one thread; only elapsed_us may differ. Real data: the
// project's mocap imported into its scenes, a world written by world-bench
// in the breakfast room (avatars, held and thrown objects), and the GPU
// backend with several threads against the CPU with one.

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/common/temp_dir_test.h"
#include "tests/tools/run_binary.h"

namespace sweptccd {
namespace {

using testing::RunResult;

const std::string kBinary = SWEPTCCD_BINARY;
const std::string kData = SWEPTCCD_DATA_DIR;

// The record lines with every "elapsed_us" value taken out (nothing else is
// touched: stats, brackets, witnesses and order must match as they are).
std::vector<std::string> WithoutElapsed(const std::string& text) {
  static const std::regex elapsed("\"elapsed_us\":[^,}]*");
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
    out.push_back(std::regex_replace(line, elapsed, "\"elapsed_us\":0"));
  return out;
}

// Also without "stats" (a GPU record counts its round trips there).
std::vector<std::string> WithoutTiming(const std::string& text) {
  static const std::regex stats("\"stats\":\\{[^}]*\\}");
  std::vector<std::string> out = WithoutElapsed(text);
  for (std::string& line : out) line = std::regex_replace(line, stats, "\"stats\":{}");
  return out;
}

int Count(const std::vector<std::string>& lines, const std::string& what) {
  int n = 0;
  for (const std::string& l : lines) n += l.find(what) != std::string::npos;
  return n;
}

class ThreadsCommandTest : public test::TempDirTest {
 protected:
  ThreadsCommandTest() : TempDirTest("threads") {}
  RunResult Run(const std::vector<std::string>& args, const std::string& out = "out.txt") {
    return testing::RunBinary(kBinary, args, Path(out), Path("err.txt"), 300);
  }
  // A clip imported at 30 Hz standing on the floor of a z-up scene.
  void Import(const std::string& clip) {
    const RunResult r = Run({"import-bvh", "--bvh", kData + "/mocap/" + clip, "--up", "z", "--rate",
                             "30", "--offset", "0", "0", "0.02", "--skeleton-out",
                             Path("skel.json"), "--poses-out", Path("poses.jsonl")});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  }
  std::string Query(const std::string& env, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {
        "query", "--skeleton",         Path("skel.json"), "--poses", Path("poses.jsonl"),
        "--env", kData + "/env/" + env};
    args.insert(args.end(), extra.begin(), extra.end());
    const RunResult r = Run(args);
    EXPECT_TRUE(r.exited && r.code == 0) << r.Describe();
    return r.out;
  }
};

TEST_F(ThreadsCommandTest, QueryRecordsAreTheSameForAnyThreadCount) {
  const std::string env = "morse_apartment.ply.gz";
  for (const char* clip :
       {"cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz", "boxing_toes.bvh.gz"}) {
    Import(clip);
    const std::vector<std::string> one =
        WithoutElapsed(Query(env, {"--backend", "cpu", "--threads", "1"}));
    ASSERT_GT(one.size(), 200u) << clip;
    EXPECT_GE(Count(one, "\"contact\""), 20) << clip << ": the test needs contacts";
    EXPECT_GE(Count(one, "\"free\""), 20) << clip << ": the test needs free pairs";
    for (const char* threads : {"2", "4", "7"}) {
      EXPECT_EQ(WithoutElapsed(Query(env, {"--backend", "cpu", "--threads", threads})), one)
          << clip << " with --threads " << threads;
    }
    // Per-link mode too (every touching link bracketed).
    EXPECT_EQ(WithoutElapsed(Query(env, {"--backend", "cpu", "--per-link", "--threads", "4"})),
              WithoutElapsed(Query(env, {"--backend", "cpu", "--per-link", "--threads", "1"})))
        << clip;
  }
}

TEST_F(ThreadsCommandTest, InvalidLinesKeepTheirPlace) {
  Import("cmu_02_01_walk.bvh.gz");
  // Every 10th line replaced by garbage: the invalid records must sit where
  // they sat with one thread.
  std::ifstream in(Path("poses.jsonl"));
  std::string text, line;
  for (int k = 0; std::getline(in, line); ++k) text += (k % 10 == 5 ? "{not json" : line) + "\n";
  Write("poses.jsonl", text);
  const std::vector<std::string> one =
      WithoutElapsed(Query("morse_apartment.ply.gz", {"--backend", "cpu", "--threads", "1"}));
  EXPECT_GE(Count(one, "\"invalid\""), 9);
  EXPECT_EQ(WithoutElapsed(Query("morse_apartment.ply.gz", {"--backend", "cpu", "--threads", "3"})),
            one);
}

TEST_F(ThreadsCommandTest, RefusesZeroThreads) {
  Import("cmu_02_01_walk.bvh.gz");
  const RunResult r = Run({"query", "--skeleton", Path("skel.json"), "--poses", Path("poses.jsonl"),
                           "--env", kData + "/env/morse_apartment.ply.gz", "--threads", "0"});
  EXPECT_TRUE(r.exited && r.code != 0) << r.Describe();
  EXPECT_NE(r.err.find("--threads"), std::string::npos) << r.err;
}

// A shared world written by world-bench from the project's mocap in the
// breakfast room: avatars, a held object, a thrown one.
TEST_F(ThreadsCommandTest, WorldRecordsAreTheSameForAnyThreadCount) {
  const RunResult gen = Run({"world-bench", "--out", Path("w"), "--avatars", "4", "--objects", "2",
                             "--seconds", "1", "--generate-only"});
  ASSERT_TRUE(gen.exited && gen.code == 0) << gen.Describe();
  const std::string world = Path("w/world.json");
  const RunResult one = Run({"world", "--world", world, "--backend", "cpu", "--threads", "1"});
  ASSERT_TRUE(one.exited && one.code == 0) << one.Describe();
  const std::vector<std::string> a = WithoutElapsed(one.out);
  ASSERT_GE(a.size(), 100u);
  EXPECT_GE(Count(a, "\"contact\""), 5);
  for (const char* threads : {"2", "5"}) {
    const RunResult n = Run({"world", "--world", world, "--backend", "cpu", "--threads", threads});
    ASSERT_TRUE(n.exited && n.code == 0) << n.Describe();
    EXPECT_EQ(WithoutElapsed(n.out), a) << "--threads " << threads;
  }
}

// Issue 30: the GPU backend (llvmpipe here) with several threads, their
// swept tests coalesced into shared dispatches, gives the CPU's records with
// one thread, for pairs and for a shared world.
TEST_F(ThreadsCommandTest, GpuWithThreadsGivesTheCpuRecords) {
  Import("boxing_toes.bvh.gz");
  const std::string env = "morse_apartment.ply.gz";
  const std::string gpu = Query(env, {"--backend", "gpu", "--threads", "4"});
  EXPECT_NE(gpu.find("gpu_round_trips"), std::string::npos) << "the GPU never ran";
  const std::vector<std::string> cpu =
      WithoutTiming(Query(env, {"--backend", "cpu", "--threads", "1"}));
  EXPECT_GE(Count(cpu, "\"contact\""), 20);
  EXPECT_EQ(WithoutTiming(gpu), cpu);
  EXPECT_EQ(WithoutTiming(Query(env, {"--backend", "gpu", "--threads", "3", "--per-link"})),
            WithoutTiming(Query(env, {"--backend", "cpu", "--threads", "1", "--per-link"})));

  const RunResult gen = Run({"world-bench", "--out", Path("w"), "--avatars", "4", "--objects", "2",
                             "--seconds", "1", "--generate-only"});
  ASSERT_TRUE(gen.exited && gen.code == 0) << gen.Describe();
  const std::string world = Path("w/world.json");
  const RunResult c = Run({"world", "--world", world, "--backend", "cpu", "--threads", "1"});
  const RunResult g = Run({"world", "--world", world, "--backend", "gpu", "--threads", "4"});
  ASSERT_TRUE(c.exited && c.code == 0) << c.Describe();
  ASSERT_TRUE(g.exited && g.code == 0) << g.Describe();
  EXPECT_NE(g.err.find("backend gpu"), std::string::npos) << g.err;
  EXPECT_EQ(WithoutTiming(g.out), WithoutTiming(c.out));
}

// Issue 30: `query --device-descent` (the chunk's free intervals cleared on
// the GPU, llvmpipe here, in a few dispatches; the CPU answers the rest)
// gives the CPU's records, first contact and per link.
TEST_F(ThreadsCommandTest, QueryDeviceDescentGivesTheCpuRecords) {
  Import("boxing_toes.bvh.gz");
  const std::string env = "morse_apartment.ply.gz";
  const RunResult d = Run({"query", "--skeleton", Path("skel.json"), "--poses", Path("poses.jsonl"),
                           "--env", kData + "/env/" + env, "--backend", "gpu", "--device-descent",
                           "--threads", "2", "--log-level", "info"});
  ASSERT_TRUE(d.exited && d.code == 0) << d.Describe();
  EXPECT_TRUE(std::regex_search(
      d.err, std::regex("GPU device descent: [1-9][0-9]* batches, [1-9][0-9]* dispatches, "
                        "[1-9][0-9]* intervals tested, [1-9][0-9]* cleared")))
      << d.err;
  const std::vector<std::string> cpu =
      WithoutTiming(Query(env, {"--backend", "cpu", "--threads", "1"}));
  EXPECT_GE(Count(cpu, "\"contact\""), 20);
  EXPECT_GE(Count(cpu, "\"free\""), 20);
  EXPECT_EQ(WithoutTiming(d.out), cpu);
  EXPECT_EQ(WithoutTiming(Query(
                env, {"--backend", "gpu", "--device-descent", "--threads", "3", "--per-link"})),
            WithoutTiming(Query(env, {"--backend", "cpu", "--threads", "1", "--per-link"})));
}

// Issue 30: `world --device-descent` (the environment parts of each chunk
// of records cleared on the GPU, llvmpipe here, in one batch; the CPU
// answers the rest and every part between entities) gives the CPU's records.
TEST_F(ThreadsCommandTest, WorldDeviceDescentGivesTheCpuRecords) {
  // 9 avatars 1.5 m apart: the outer ones stand in the furniture (environment
  // contacts), the others do not (free environment parts).
  const RunResult gen = Run({"world-bench", "--out", Path("w"), "--avatars", "9", "--objects", "2",
                             "--seconds", "1", "--spacing", "1.5", "--generate-only"});
  ASSERT_TRUE(gen.exited && gen.code == 0) << gen.Describe();
  const std::string world = Path("w/world.json");
  const RunResult c = Run({"world", "--world", world, "--backend", "cpu", "--threads", "1"});
  ASSERT_TRUE(c.exited && c.code == 0) << c.Describe();
  const std::vector<std::string> cpu = WithoutTiming(c.out);
  // The environment part of a record is its top-level "result" (the
  // entities' come after, in "others").
  int env_contacts = 0, env_free = 0;
  for (const std::string& line : cpu) {
    const size_t others = line.find("\"others\"");
    const std::string head = line.substr(0, others);
    env_contacts += head.find("\"result\":\"contact\"") != std::string::npos;
    env_free += head.find("\"result\":\"free\"") != std::string::npos;
  }
  EXPECT_GE(env_contacts, 50);
  EXPECT_GE(env_free, 50);
  for (const char* threads : {"1", "3"}) {
    const RunResult d = Run({"world", "--world", world, "--backend", "gpu", "--device-descent",
                             "--threads", threads, "--log-level", "info"});
    ASSERT_TRUE(d.exited && d.code == 0) << d.Describe();
    EXPECT_TRUE(std::regex_search(
        d.err, std::regex("GPU device descent: [1-9][0-9]* batches, [1-9][0-9]* dispatches, "
                          "[1-9][0-9]* intervals tested, [1-9][0-9]* cleared")))
        << d.err;
    EXPECT_EQ(WithoutTiming(d.out), cpu) << "--threads " << threads;
  }
  const RunResult cl = Run({"world", "--world", world, "--backend", "cpu", "--per-link"});
  const RunResult dl =
      Run({"world", "--world", world, "--backend", "gpu", "--device-descent", "--per-link"});
  ASSERT_TRUE(cl.exited && cl.code == 0) << cl.Describe();
  ASSERT_TRUE(dl.exited && dl.code == 0) << dl.Describe();
  EXPECT_EQ(WithoutTiming(dl.out), WithoutTiming(cl.out));
}

}  // namespace
}  // namespace sweptccd
