#include "service/ops/systemd_notifier.h"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <cstring>
#include <string>

namespace sweptccd {

namespace {

void Notify(const std::string& message) {
  const int r = sd_notify(0, message.c_str());
  if (r < 0) spdlog::warn("sd_notify({}): {}", message, std::strerror(-r));
}

}  // namespace

SystemdNotifier::SystemdNotifier() {
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdog_period_ = std::chrono::microseconds(usec / 2);
    spdlog::info("systemd watchdog: every {} ms from the loop", usec / 2000);
  }
}

void SystemdNotifier::Ready(const char* status_text) {
  Notify(std::string("READY=1\nSTATUS=") + status_text);
  ready_ = true;
}

void SystemdNotifier::Stopping() { Notify("STOPPING=1"); }

void SystemdNotifier::MaybeWatchdog(std::chrono::steady_clock::time_point now) {
  if (!watchdog_enabled() || !ready_ || now < next_watchdog_) return;
  Notify("WATCHDOG=1");
  next_watchdog_ = now + watchdog_period_;
}

}  // namespace sweptccd
