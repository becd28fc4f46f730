#pragma once
// SIGINT/SIGTERM as a file descriptor, for the long-running tools
// (`simulate-tracker`, `monitor`): their loops poll() it next to LCM's fd and
// their timers, as sweptccd-service does, so Ctrl-C ends them cleanly (with
// their summary) instead of killing them.

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
};

}  // namespace sweptccd
