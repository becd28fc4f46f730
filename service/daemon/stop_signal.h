#pragma once
// SIGINT/SIGTERM as a file descriptor (the self-pipe), the one stop signal of
// the processes that run until stopped: sweptccd-service waits on it before
// stopping its Daemon, the long-running tools (`simulate-tracker`, `monitor`)
// poll() it next to LCM's fd and their timers, so Ctrl-C ends them cleanly
// (in-flight work answered, summaries printed) instead of killing them.

#include <chrono>

namespace sweptccd {

/// Installs SIGINT and SIGTERM handlers that write one byte to a pipe.
/// Construct once per process, on the main thread; the handlers stay
/// installed (the pipe too) until the process exits. Throws InputError when
/// the pipe cannot be created.
class StopSignal {
 public:
  StopSignal();
  StopSignal(const StopSignal&) = delete;
  StopSignal& operator=(const StopSignal&) = delete;

  /// The read end of the pipe: readable once a signal arrived.
  int fd() const;
  /// Whether a signal arrived (does not block).
  bool stopped() const;
  /// Sleeps until `deadline` or a signal, whichever comes first. Returns
  /// stopped().
  bool WaitUntil(std::chrono::steady_clock::time_point deadline) const;
  /// Sleeps until a signal arrives (returns at once if one already has).
  void Wait() const;
};

}  // namespace sweptccd
