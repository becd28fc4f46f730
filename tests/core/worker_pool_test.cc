// WorkerPool (core/worker_pool.h): every item once, on a worker in range, one
// item at a time per worker, exceptions rethrown, many Runs in a row, and
// threads that cannot start reported by an exception, not an abort.

#include "core/worker_pool.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace sweptccd {
namespace {

TEST(WorkerPoolTest, EveryItemOnceOnAWorkerInRange) {
  for (int threads : {1, 2, 5}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.size(), threads);
    for (size_t count : {0u, 1u, 3u, 1000u}) {
      std::vector<std::atomic<int>> seen(count);
      std::vector<std::atomic<int>> busy(static_cast<size_t>(threads));
      std::atomic<bool> overlap{false}, bad_worker{false};
      pool.Run(count, [&](size_t i, int w) {
        if (w < 0 || w >= threads) {
          bad_worker = true;
          return;
        }
        if (busy[w]++ != 0) overlap = true;  // Per-worker state needs no lock.
        ++seen[i];
        --busy[w];
      });
      for (size_t i = 0; i < count; ++i) EXPECT_EQ(seen[i], 1) << i;
      EXPECT_FALSE(overlap);
      EXPECT_FALSE(bad_worker);
    }
  }
}

TEST(WorkerPoolTest, ExceptionsComeBackAndThePoolGoesOn) {
  WorkerPool pool(3);
  EXPECT_THROW(pool.Run(100,
                        [](size_t i, int) {
                          if (i == 37) throw std::runtime_error("item 37");
                        }),
               std::runtime_error);
  std::atomic<int> n{0};
  pool.Run(50, [&](size_t, int) { ++n; });
  EXPECT_EQ(n, 50);
  EXPECT_THROW(WorkerPool(0), std::invalid_argument);
  EXPECT_GE(DefaultThreadCount(), 1);
}

// The tasks (threads) of real user `uid`, all processes (/proc/*/status).
int TasksOfUser(uid_t uid) {
  int tasks = 0;
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    std::ifstream status(entry.path() / "status");
    std::string line;
    bool mine = false;
    while (std::getline(status, line)) {
      unsigned real = 0;
      if (std::sscanf(line.c_str(), "Uid: %u", &real) == 1) mine = real == uid;
      int threads = 0;
      if (mine && std::sscanf(line.c_str(), "Threads: %d", &threads) == 1) tasks += threads;
    }
  }
  return tasks;
}

// A task limit reached after a few threads started: the constructor throws
// std::system_error having joined those (a joinable std::thread left in a
// destroyed vector would call std::terminate). In a child process, as
// nobody when run as root (whose limit is not enforced), limited to its
// user's tasks plus 3: exit 0 when the exception came, 1 when the pool was
// built, a signal for an abort; a hang is killed after 10 s.
TEST(WorkerPoolTest, ThreadsThatCannotStartThrowInsteadOfAborting) {
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    if (geteuid() == 0 && (setgid(65534) != 0 || setuid(65534) != 0)) _exit(3);
    const auto limit = static_cast<rlim_t>(TasksOfUser(getuid()) + 3);
    const rlimit few{limit, limit};
    if (setrlimit(RLIMIT_NPROC, &few) != 0) _exit(4);
    try {
      WorkerPool pool(16);
      _exit(1);
    } catch (const std::system_error&) {
      _exit(0);
    }
  }
  int status = 0;
  pid_t done = 0;
  for (int tries = 0; tries < 1000 && done == 0; ++tries) {  // At most 10 s.
    done = waitpid(child, &status, WNOHANG);
    if (done == 0) usleep(10000);
  }
  if (done == 0) {  // Hung: threads left waiting on a destroyed condition variable, say.
    kill(child, SIGKILL);
    waitpid(child, &status, 0);
    FAIL() << "the child hung after a thread failed to start";
  }
  ASSERT_EQ(done, child);
  ASSERT_TRUE(WIFEXITED(status)) << "the child ended by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: the pool started its threads despite the limit";
}

}  // namespace
}  // namespace sweptccd
