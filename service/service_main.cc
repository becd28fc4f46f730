// sweptccd-service: the collision daemon. Parses flags (service_flags.h),
// builds the Daemon from the configuration they name, starts it and waits for
// SIGINT or SIGTERM; then in-flight work is finished and published before
// exit.

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "core/errors.h"
#include "msgs/text.h"
#include "service/daemon/daemon.h"
#include "service/daemon/stop_signal.h"
#include "service/ops/operations.h"
#include "service/service_flags.h"

int main(int argc, char** argv) {
  using namespace sweptccd;
  spdlog::set_default_logger(spdlog::stderr_color_mt("sweptccd-service"));
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");

  CLI::App app{"sweptccd-service: continuous collision answers for tracked avatars over LCM"};
  ServiceFlags flags;
  AddServiceFlags(&app, &flags);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "error: sweptccd-service: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }

  try {
    const StopSignal stop;  // Before any thread starts.
    const ServiceConfig config = BuildServiceConfig(flags);
    const std::string agones_url = Operations::AgonesUrl(config.ops);  // Before the scene.
    Daemon daemon(config);  // The scene loaded, the backend calibrated.
    Operations ops(config.ops, agones_url, daemon.service(), daemon.room());
    daemon.SetLoopTick([&ops] { ops.Tick(); });
    // The loop (which calls ops) ends before ops is destroyed, whatever throws.
    struct StopDaemonFirst {
      Daemon* daemon;
      ~StopDaemonFirst() { daemon->Stop(); }
    } stop_daemon_first{&daemon};
    daemon.Start();
    ops.Ready();  // systemd READY=1, Agones Ready, /metrics served.
    stop.Wait();
    ops.Stopping();
    daemon.Stop();
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}
