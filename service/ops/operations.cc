#include "service/ops/operations.h"

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <thread>

#include "service/collision_service.h"
#include "service/ops/agones_lifecycle.h"
#include "service/ops/metrics_server.h"
#include "service/ops/prometheus_text.h"
#include "service/ops/room_name.h"
#include "service/ops/systemd_notifier.h"

namespace sweptccd {

struct Operations::Impl {
  OpsOptions options;
  const CollisionService* service;
  SystemdNotifier systemd;
  std::unique_ptr<MetricsServer> metrics;
  std::unique_ptr<AgonesLifecycle> agones;
  std::string wedge_file;  // The test hook's file; empty: none.
  bool stopped = false;
};

std::string Operations::AgonesUrl(const OpsOptions& options) {
  return options.agones.enabled ? AgonesSdk::BaseUrlFromEnvironment() : std::string();
}

Operations::Operations(const OpsOptions& options, const std::string& agones_url,
                       const CollisionService* service, RoomName* room)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->service = service;
  if (const char* f = std::getenv("SWEPTCCD_TEST_WEDGE_FILE")) impl_->wedge_file = f;
  if (!options.metrics.listen.empty()) {
    impl_->metrics = std::make_unique<MetricsServer>(options.metrics.listen, [service, room] {
      return RenderRoomMetrics(room->Get(), service->Status(), service->latency_histogram());
    });
  }
  if (options.agones.enabled) {
    impl_->agones = std::make_unique<AgonesLifecycle>(
        AgonesSdk(agones_url), options.agones, [service] { return service->live_clients(); }, room);
  }
}

Operations::~Operations() { Stopping(); }

void Operations::Tick() {
  while (!impl_->wedge_file.empty() && access(impl_->wedge_file.c_str(), F_OK) == 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  impl_->systemd.MaybeWatchdog(std::chrono::steady_clock::now());
  if (impl_->agones) impl_->agones->Beat();
}

void Operations::Ready() {
  if (impl_->metrics) impl_->metrics->Start();
  impl_->systemd.Ready("scene loaded, backend calibrated, answering");
  if (impl_->agones) {
    impl_->agones->Beat();  // The loop runs (Daemon::Start).
    impl_->agones->Start();
  }
}

void Operations::Stopping() {
  if (impl_->stopped) return;
  impl_->stopped = true;
  if (impl_->agones) impl_->agones->Stop();
  impl_->systemd.Stopping();
  if (impl_->metrics) impl_->metrics->Stop();
}

}  // namespace sweptccd
