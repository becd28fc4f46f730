// `sweptccd bench` at a small size (one scene, one clip, 30 pairs), run as
// the real binary with its peers: the table has the Bullet and FCL columns,
// its counts agree with each other (Bullet's misses are among our certified
// contacts), every row has its four met/missed lines, and the total counts
// them. A run without peers certifies the same contacts. Counts and
// structure only: times are never asserted.

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
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

// The table's rows by clip (first 18 characters), each column by its header.
std::map<std::string, std::map<std::string, std::string>> Rows(const std::string& out) {
  std::map<std::string, std::map<std::string, std::string>> rows;
  std::istringstream in(out);
  std::string line;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::vector<std::string> f;
    for (std::string w; words >> w;) f.push_back(w);
    if (!f.empty() && f[0] == "scene") {
      header = f;
      continue;
    }
    if (header.empty() || f.size() < 3 || f[0] != "morse_apartment") continue;
    if (f[2] == "ALL") f.erase(f.begin() + 3);  // "ALL CLIPS": one column.
    if (f.size() != header.size()) continue;
    for (size_t k = 0; k < f.size(); ++k) rows[f[2]][header[k]] = f[k];
  }
  return rows;
}

class BenchCommandTest : public test::TempDirTest {
 protected:
  BenchCommandTest() : TempDirTest("bench") {}
  RunResult Run(const std::vector<std::string>& args) {
    return testing::RunBinary(kBinary, args, Path("out.txt"), Path("err.txt"), 300);
  }
};

TEST_F(BenchCommandTest, PrintsOursBesideBulletAndFcl) {
  const std::vector<std::string> base = {
      "bench", "--scene", "morse_apartment", "--clip", "cmu_02_01_walk.bvh", "--max-pairs", "30",
      "--gpu", "off",     "--clock",         "thread"};
  const RunResult r = Run(base);
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const auto rows = Rows(r.out);
  ASSERT_EQ(rows.size(), 2u) << r.out;  // The clip and ALL.
  const auto& clip = rows.at("cmu_02_01_walk.bvh");
  const auto& all = rows.at("ALL");
  for (const char* column : {"pairs", "contact", "undec", "median_us", "p99_us", "fcl_med",
                             "missed", "bul_med", "bul_p99", "bul/ours", "b/o_p99", "bmiss"}) {
    ASSERT_TRUE(clip.count(column)) << column << "\n" << r.out;
  }
  const int pairs = std::stoi(clip.at("pairs"));
  const int contacts = std::stoi(clip.at("contact"));
  EXPECT_EQ(pairs, 30);
  EXPECT_EQ(all.at("pairs"), clip.at("pairs"));
  EXPECT_EQ(all.at("contact"), clip.at("contact"));
  EXPECT_EQ(std::stoi(clip.at("undec")), 0);
  EXPECT_GT(contacts, 0);
  EXPECT_LE(contacts, pairs);
  // Misses are pairs we certify as contact that the peer does not see.
  const int bullet_misses = std::stoi(clip.at("bmiss"));
  const int fcl_misses = std::stoi(clip.at("missed"));
  EXPECT_LE(bullet_misses, contacts);
  EXPECT_LE(fcl_misses, contacts);
  // Bullet's uncertified sweep misses at least one of these 30 pairs
  // (measured: 1), so the count is really computed.
  EXPECT_GE(bullet_misses, 1) << r.out;
  for (const char* positive : {"median_us", "p99_us", "fcl_med", "bul_med", "bul_p99"}) {
    EXPECT_GT(std::stod(clip.at(positive)), 0) << positive;
  }
  EXPECT_LE(std::stod(clip.at("median_us")), std::stod(clip.at("p99_us")));
  EXPECT_LE(std::stod(clip.at("bul_med")), std::stod(clip.at("bul_p99")));

  // Four targets per row, each met or missed, and the total counts them.
  const std::regex target(
      "median<=Bullet \\(x[0-9.]+\\) (met|MISSED);  median 5x FCL \\(x[0-9.]+\\) (met|MISSED);  "
      "p99 10x Bullet \\(x[0-9.]+\\) (met|MISSED);  p99<=5x median \\(x[0-9.]+\\) (met|MISSED)");
  int lines = 0, met = 0;
  for (auto it = std::sregex_iterator(r.out.begin(), r.out.end(), target);
       it != std::sregex_iterator(); ++it) {
    ++lines;
    for (int k = 1; k <= 4; ++k) met += (*it)[k] == "met";
  }
  EXPECT_EQ(lines, 2) << r.out;
  std::smatch total;
  ASSERT_TRUE(std::regex_search(r.out, total, std::regex("targets met: ([0-9]+) of ([0-9]+)")))
      << r.out;
  EXPECT_EQ(std::stoi(total[1]), met);
  EXPECT_EQ(std::stoi(total[2]), 8);

  // Without peers: the same certified contacts, no peer columns filled.
  std::vector<std::string> no_peers = base;
  no_peers.push_back("--no-peers");
  const RunResult q = Run(no_peers);
  ASSERT_TRUE(q.exited && q.code == 0) << q.Describe();
  const auto quiet = Rows(q.out);
  ASSERT_TRUE(quiet.count("cmu_02_01_walk.bvh")) << q.out;
  EXPECT_EQ(quiet.at("cmu_02_01_walk.bvh").at("contact"), clip.at("contact"));
  EXPECT_EQ(quiet.at("cmu_02_01_walk.bvh").at("pairs"), clip.at("pairs"));
  // Only our own target is judged without the peers; theirs say n/a.
  const std::regex own(
      "median<=Bullet n/a;  median 5x FCL n/a;  p99 10x Bullet n/a \\(--no-peers\\);  "
      "p99<=5x median \\(x[0-9.]+\\) (met|MISSED)");
  EXPECT_EQ(
      std::distance(std::sregex_iterator(q.out.begin(), q.out.end(), own), std::sregex_iterator()),
      2)
      << q.out;
  EXPECT_FALSE(std::regex_search(q.out, std::regex("\\(x0\\.00\\) MISSED"))) << q.out;
  ASSERT_TRUE(std::regex_search(q.out, total, std::regex("targets met: ([0-9]+) of ([0-9]+)")))
      << q.out;
  EXPECT_EQ(std::stoi(total[2]), 2);
}

// Issue 30: `bench --sweep` prints, for every batch size, the CPU on one
// thread, the CPU on --threads threads, the GPU backend (llvmpipe here)
// with its dispatches, and the device descent with its own; every method
// answered every pair alike (differ 0);
// the pairs cycle to fill at least 3 batches. Counts only, never times.
TEST_F(BenchCommandTest, SweepPrintsEveryMethodAndBatchSize) {
  const RunResult r = Run({"bench", "--sweep", "--scene", "morse_apartment", "--clip",
                           "cmu_05_06_dance_cartwheel_pirouettes_jete.bvh", "--max-pairs", "150",
                           "--sweep-sizes", "1", "16", "64", "--threads", "3", "--no-peers"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  EXPECT_NE(r.out.find("the CPU backend on 3 threads and the GPU backend on 3 threads"),
            std::string::npos)
      << r.out;
  std::istringstream in(r.out);
  std::string line;
  std::map<std::string, int> rows;
  const std::regex row(
      "\\| morse_apartment \\| ([0-9]+) \\| (cpu, 1 thread|cpu, all threads|gpu, all "
      "threads|gpu descent, all threads) "
      "\\| ([0-9]+) \\| [0-9.]+ \\| [0-9.]+ \\| [0-9.]+ \\| [0-9.]+ \\| ([-0-9]+) \\| "
      "([-0-9.]+) \\| ([-0-9.]+) \\| ([0-9]+) \\| (-|[0-9.]+ / [0-9.]+ / [0-9.]+ / [0-9.]+) "
      "\\|");
  while (std::getline(in, line)) {
    std::smatch m;
    if (!std::regex_match(line, m, row)) continue;
    const int batch = std::stoi(m[1]);
    ++rows[m[1].str() + " " + m[2].str()];
    // 150 pairs in whole batches, at least 3 batches.
    EXPECT_EQ(std::stoi(m[3]), std::max(150 + (batch - 150 % batch) % batch, 3 * batch)) << line;
    EXPECT_EQ(m[7], "0") << "methods disagree: " << line;
    if (m[2] == "gpu, all threads" || m[2] == "gpu descent, all threads") {
      EXPECT_GT(std::stoi(m[4]), 0) << "the GPU never dispatched: " << line;
    } else {
      EXPECT_EQ(m[4], "-") << line;
    }
    // Where the descent's time went: its rows only.
    EXPECT_EQ(m[8] == "-", m[2] != "gpu descent, all threads") << line;
  }
  EXPECT_EQ(rows.size(), 12u) << r.out;
  for (const auto& [key, n] : rows) EXPECT_EQ(n, 1) << key;
}

// `--write-scene` (issue 30: bench scenes for the daemon): the placed meshes
// as one binary PLY of exactly the scene's triangles, which loads back to
// the same geometry: `query` on the written apartment gives the records of
// `query` on the bundled file. Unknown scenes and a missing --scene are
// refused with one line.
std::string WithoutTimes(std::string records) {
  records = std::regex_replace(records, std::regex("\"elapsed_us\":[^,]*,"), "");
  return std::regex_replace(records, std::regex("\"stats\":\\{[^}]*\\},"), "");
}

TEST_F(BenchCommandTest, WriteSceneWritesThePlacedMeshesExactly) {
  const RunResult dragon =
      Run({"bench", "--scene", "breakfast+dragon_1.1M", "--write-scene", Path("dragon.ply")});
  ASSERT_TRUE(dragon.exited && dragon.code == 0) << dragon.Describe();
  EXPECT_NE(dragon.out.find("breakfast+dragon_1.1M: 1140952 triangles written"), std::string::npos)
      << dragon.out;
  std::ifstream ply(Path("dragon.ply"), std::ios::binary);
  std::string header, line;
  int64_t vertices = -1, faces = -1;
  while (std::getline(ply, line)) {
    header += line + "\n";
    if (line.rfind("element vertex ", 0) == 0) vertices = std::stoll(line.substr(15));
    if (line.rfind("element face ", 0) == 0) faces = std::stoll(line.substr(13));
    if (line == "end_header") break;
  }
  EXPECT_EQ(faces, 1140952);
  ASSERT_GT(vertices, 0);
  ply.seekg(0, std::ios::end);
  EXPECT_EQ(static_cast<int64_t>(ply.tellg()),
            static_cast<int64_t>(header.size()) + 12 * vertices + 13 * faces);

  const RunResult morse =
      Run({"bench", "--scene", "morse_apartment", "--write-scene", Path("morse.ply")});
  ASSERT_TRUE(morse.exited && morse.code == 0) << morse.Describe();
  const RunResult walk =
      Run({"import-bvh", "--bvh", std::string(SWEPTCCD_DATA_DIR) + "/mocap/cmu_02_01_walk.bvh.gz",
           "--up", "z", "--rate", "30", "--offset", "0", "0", "0.02", "--skeleton-out",
           Path("skel.json"), "--poses-out", Path("poses.jsonl")});
  ASSERT_TRUE(walk.exited && walk.code == 0) << walk.Describe();
  std::vector<std::string> query = {
      "query", "--skeleton", Path("skel.json"), "--poses", Path("poses.jsonl"), "--backend",
      "cpu",   "--env"};
  std::vector<std::string> bundled = query, written = query;
  bundled.push_back(std::string(SWEPTCCD_DATA_DIR) + "/env/morse_apartment.ply.gz");
  written.push_back(Path("morse.ply"));
  const RunResult a = Run(bundled), b = Run(written);
  ASSERT_TRUE(a.exited && a.code == 0) << a.Describe();
  ASSERT_TRUE(b.exited && b.code == 0) << b.Describe();
  EXPECT_NE(a.out.find("\"result\":\"contact\""), std::string::npos) << "no contact to compare";
  EXPECT_EQ(WithoutTimes(a.out), WithoutTimes(b.out));

  const RunResult unknown = Run({"bench", "--scene", "no_such_scene", "--gpu", "off"});
  EXPECT_TRUE(unknown.exited && unknown.code != 0) << unknown.Describe();
  EXPECT_NE(unknown.err.find("no scene 'no_such_scene'"), std::string::npos) << unknown.err;
  const RunResult two = Run({"bench", "--write-scene", Path("x.ply")});
  EXPECT_TRUE(two.exited && two.code != 0) << two.Describe();
  EXPECT_NE(two.err.find("--write-scene needs exactly one --scene"), std::string::npos) << two.err;
}

}  // namespace
}  // namespace sweptccd
