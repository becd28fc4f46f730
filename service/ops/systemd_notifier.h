#pragma once
// systemd's notify protocol through libsystemd (sd_notify): READY=1 once the
// scene is loaded and the backend calibrated, WATCHDOG=1 from the daemon's
// loop, STOPPING=1 on the way out (deploy/sweptccd-service.service is
// Type=notify with WatchdogSec=). Without NOTIFY_SOCKET (not under systemd,
// or a test) every call does nothing.

#include <atomic>
#include <chrono>

namespace sweptccd {

class SystemdNotifier {
 public:
  /// Reads NOTIFY_SOCKET and WATCHDOG_USEC (sd_watchdog_enabled).
  SystemdNotifier();

  void Ready(const char* status_text);
  void Stopping();
  /// WATCHDOG=1 when half the watchdog interval passed since the last one;
  /// nothing without a watchdog, nor before Ready() (READY=1 comes first). Call from the loop whose
  /// life it vouches for.
  void MaybeWatchdog(std::chrono::steady_clock::time_point now);
  /// Whether systemd asked for watchdog pings, and how often at least.
  bool watchdog_enabled() const { return watchdog_period_.count() > 0; }

 private:
  std::chrono::microseconds watchdog_period_{0};  // Half of WATCHDOG_USEC.
  std::atomic<bool> ready_{false};
  std::chrono::steady_clock::time_point next_watchdog_{};
};

}  // namespace sweptccd
