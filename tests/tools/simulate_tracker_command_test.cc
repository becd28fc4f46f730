// `sweptccd simulate-tracker --poses`: the pose file is read through the
// core's PoseLineReader (the same blank lines, utimes and line cap as
// `sweptccd query`) and streamed: poses go out while the file is still being
// written. The messages are read back from an LCM log written through the
// file:// provider (no network).

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <thread>
#include <vector>

#include "sweptccd/tracker_pose_t.hpp"
#include "tests/common/temp_dir_test.h"
#include "tests/tools/run_binary.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;
using testing::RunBinary;
using testing::RunResult;

class SimulateTrackerTest : public test::TempDirTest {
 protected:
  SimulateTrackerTest() : TempDirTest("simulate_test") {}
  // Runs the command with its messages logged to log_path.
  RunResult Simulate(const std::string& poses, const std::string& log_path,
                     std::vector<std::string> extra = {}) const {
    std::vector<std::string> args = {"simulate-tracker", "--poses", poses, "--lcm-url",
                                     "file://" + log_path + "?mode=w", "--speed", "1000000",
                                     "--client", "c0"};
    args.insert(args.end(), extra.begin(), extra.end());
    return RunBinary(SWEPTCCD_BINARY, args, Path("out.txt"), Path("err.txt"), 60);
  }

};

// The messages in an LCM log, up to the first incomplete event.
std::vector<tracker_pose_t> ReadLog(const std::string& path) {
  std::vector<tracker_pose_t> out;
  if (!fs::exists(path)) return out;
  lcm::LogFile log(path, "r");
  if (!log.good()) return out;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    tracker_pose_t m;
    if (m.decode(ev->data, 0, ev->datalen) < 0) break;
    out.push_back(m);
  }
  return out;
}

std::string PoseLine(const std::string& utime, double x) {
  return "{\"utime\": " + utime + ", \"links\": [[" + std::to_string(x) + ", 0, 0, 1, 0, 0, 0]]}";
}

// Regression: `simulate-tracker --poses` read the whole file before sending
// anything (1.4 GB after 45 s on 10 M lines). A FIFO's writer sends 1000
// lines and keeps it open until the first messages are in the log (bounded
// wait); only then does the file end.
TEST_F(SimulateTrackerTest, StreamsPosesBeforeTheFileEnds) {
  const std::string fifo = Path("poses.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string log = Path("poses.lcmlog");
  RunResult result;
  std::thread tool([&] { result = Simulate(fifo, log); });
  // Open for writing once the tool opened it for reading (bounded).
  int fd = -1;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (fd < 0 && std::chrono::steady_clock::now() < deadline) {
    fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd < 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_GE(fd, 0) << "simulate-tracker never opened the FIFO";
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  auto write_line = [&](const std::string& line) {
    const std::string text = line + "\n";
    ASSERT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  };
  for (int k = 0; k < 1000; ++k) write_line(PoseLine(std::to_string(1000000 + 1000 * k), k));
  size_t seen_while_open = 0;
  const auto wait_end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (seen_while_open == 0 && std::chrono::steady_clock::now() < wait_end) {
    seen_while_open = ReadLog(log).size();
    if (seen_while_open == 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  write_line(PoseLine("2000000", 1000));
  ::close(fd);
  tool.join();
  EXPECT_GT(seen_while_open, 0u) << "no pose was sent before the file ended";
  ASSERT_TRUE(result.exited && result.code == 0) << result.Describe();
  const std::vector<tracker_pose_t> sent = ReadLog(log);
  ASSERT_EQ(sent.size(), 1001u);
  for (size_t k = 0; k < sent.size(); ++k) {
    EXPECT_EQ(sent[k].seq, static_cast<int64_t>(k));
    EXPECT_EQ(sent[k].position[0][0], static_cast<double>(k));
  }
  EXPECT_NE(result.out.find("simulate-tracker: sent 1001, dropped 0, late 0"), std::string::npos)
      << result.out;
}

// Regression: simulate-tracker had its own parser (another blank-line rule,
// integer-only utime), so a file `query` accepts could be refused. Blank
// lines of any whitespace, `1000000.0` utimes and CRLF ends are accepted;
// a line that is no pose (garbage, a wrong link count, over the line cap) is
// skipped with a warning naming its line and counted; a zero quaternion is
// sent as written (the daemon judges it, as query does).
TEST_F(SimulateTrackerTest, AcceptsWhatQueryAcceptsAndSkipsLinesThatAreNoPose) {
  const std::string text = PoseLine("1000000.0", 0) + "\n" +       // line 1
                           " \t\f\v\r\n" +                          // line 2: blank
                           "\n" +                                   // line 3: blank
                           PoseLine("1033333", 1) + "\r\n" +        // line 4
                           "not json\n" +                           // line 5: skipped
                           "{\"utime\": 1050000, \"links\": []}\n" +  // line 6: skipped
                           PoseLine("1066666.0", 2) + "\n" +        // line 7
                           PoseLine("1070000", 9) + std::string(200000, ' ') + "\n" +  // line 8
                           "{\"utime\": 1100000, \"links\": [[3, 0, 0, 0, 0, 0, 0]]}";  // line 9
  const std::string poses = Write("poses.jsonl", text);
  const std::string log = Path("poses.lcmlog");
  const RunResult r = Simulate(poses, log);
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::vector<tracker_pose_t> sent = ReadLog(log);
  ASSERT_EQ(sent.size(), 4u) << r.Describe();
  const int64_t utimes[] = {1000000, 1033333, 1066666, 1100000};
  for (size_t k = 0; k < sent.size(); ++k) {
    EXPECT_EQ(sent[k].utime, utimes[k]);
    EXPECT_EQ(sent[k].seq, static_cast<int64_t>(k));
    EXPECT_EQ(sent[k].position[0][0], static_cast<double>(k));
  }
  EXPECT_EQ(sent[3].orientation[0][0], 0.0);  // Sent as written.
  EXPECT_NE(r.err.find(poses + ": line 5: not valid JSON"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(poses + ": line 6: 'links' has 0 entries, the skeleton has 1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(poses + ": line 8: longer than the cap of"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("skipped 3 malformed line(s)"), std::string::npos) << r.out;
  // `sweptccd query` on the same file counts the same lines: 5 counted lines
  // after the first, so 5 records (3 of them invalid poses).
}

TEST_F(SimulateTrackerTest, LoopReopensTheFileAndKeepsSeqAndUtimeIncreasing) {
  const std::string poses =
      Write("poses.jsonl", PoseLine("1000", 0) + "\n\n" + PoseLine("2000", 1) + "\n");
  const std::string log = Path("loop.lcmlog");
  const RunResult r = Simulate(poses, log, {"--loop", "3"});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const std::vector<tracker_pose_t> sent = ReadLog(log);
  ASSERT_EQ(sent.size(), 6u);
  // loop_span = last - first + one interval = 2000 us.
  const int64_t utimes[] = {1000, 2000, 3000, 4000, 5000, 6000};
  for (size_t k = 0; k < sent.size(); ++k) {
    EXPECT_EQ(sent[k].seq, static_cast<int64_t>(k));
    EXPECT_EQ(sent[k].utime, utimes[k]);
  }
}

TEST_F(SimulateTrackerTest, FileWithoutAnyPoseIsRefused) {
  const std::string poses = Write("none.jsonl", "\n  \ngarbage\n");
  const RunResult r = Simulate(poses, Path("none.lcmlog"));
  EXPECT_TRUE(r.exited && r.code == 2) << r.Describe();
  EXPECT_NE(r.err.find("error: " + poses + ": no pose to send"), std::string::npos) << r.err;
}

// The shared world's join filters: refused before anything is sent when
// malformed or given without --join, each with one line naming the flag.
TEST_F(SimulateTrackerTest, MalformedJoinFiltersAreRefusedBeforeSending) {
  const std::string poses = Write("one.jsonl", PoseLine("1000", 0) + "\n" + PoseLine("2000", 0));
  const std::string skeleton = Write(
      "one.json", R"({"name": "one", "links": [{"name": "hand", "parent": null, "a": [0, 0, 0],
      "b": [0.1, 0, 0], "radius": 0.05}]})");
  struct Case {
    std::vector<std::string> extra;
    std::string must_contain;
  };
  const std::vector<Case> cases = {
      {{"--join-ignore-entity", "hand:bob"}, "sent with a join: give --join"},
      {{"--join-ignore", "hand:0"}, "sent with a join: give --join"},
      {{"--join", "--skeleton", skeleton, "--join-ignore-entity", "hand"}, "expected LINK:ENTITY"},
      {{"--join", "--skeleton", skeleton, "--join-ignore-entity", "hand::x"},
       "expected LINK:ENTITY"},
      {{"--join", "--skeleton", skeleton, "--join-ignore-entity", "a:b:c:d"},
       "given by its index"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string log = Path("refused" + std::to_string(i) + ".lcmlog");
    const RunResult r = Simulate(poses, log, cases[i].extra);
    EXPECT_TRUE(r.exited && r.code == 2) << i << ": " << r.Describe();
    EXPECT_NE(r.err.find(cases[i].must_contain), std::string::npos) << i << ": " << r.err;
    EXPECT_TRUE(ReadLog(log).empty()) << i;
  }
}

}  // namespace
}  // namespace sweptccd
