#include "service/daemon/stop_signal.h"

#include <poll.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>

#include "core/errors.h"

namespace sweptccd {
namespace {

int g_pipe[2] = {-1, -1};

void OnSignal(int) {
  const char byte = 1;
  // Async-signal-safe: one write to the pipe the main loop polls.
  [[maybe_unused]] const ssize_t n = write(g_pipe[1], &byte, 1);
}

}  // namespace

StopSignal::StopSignal() {
  if (g_pipe[0] < 0) {
    if (pipe(g_pipe) != 0) throw InputError("cannot create the signal pipe");
    struct sigaction action {};
    action.sa_handler = OnSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
  }
}

int StopSignal::fd() const { return g_pipe[0]; }

bool StopSignal::stopped() const {
  pollfd p{g_pipe[0], POLLIN, 0};
  return poll(&p, 1, 0) > 0 && (p.revents & POLLIN);
}

bool StopSignal::WaitUntil(std::chrono::steady_clock::time_point deadline) const {
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return stopped();
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - now).count();
    const timespec timeout{static_cast<time_t>(ns / 1000000000),
                           static_cast<long>(ns % 1000000000)};
    pollfd p{g_pipe[0], POLLIN, 0};
    const int ready = ppoll(&p, 1, &timeout, nullptr);
    if (ready > 0) return true;
    if (ready < 0 && errno != EINTR) return stopped();
  }
}

void StopSignal::Wait() const {
  for (;;) {
    pollfd p{g_pipe[0], POLLIN, 0};
    const int ready = poll(&p, 1, -1);
    if (ready > 0) return;
    if (ready < 0 && errno != EINTR) throw InputError("waiting for a stop signal: poll failed");
  }
}

}  // namespace sweptccd
