// sweptccd-service: the collision daemon. Parses flags and the YAML
// configuration, loads the environment once, starts the service and its LCM
// transport, and waits: on LCM traffic, on the status timer and on SIGINT or
// SIGTERM (then in-flight work is finished and published before exit).

#include <poll.h>
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>

#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/errors.h"
#include "core/gpu/backend.h"
#include "core/avatar/skeleton.h"
#include "service/collision_service.h"
#include "service/lcm_transport.h"
#include "service/service_config.h"

namespace {

int g_signal_pipe[2] = {-1, -1};

void OnSignal(int) {
  const char byte = 1;
  // Async-signal-safe: one write to a pipe the main loop polls.
  [[maybe_unused]] const ssize_t n = write(g_signal_pipe[1], &byte, 1);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace sweptccd;
  spdlog::set_default_logger(spdlog::stderr_color_mt("sweptccd-service"));
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");

  CLI::App app{"sweptccd-service: continuous collision answers for tracked avatars over LCM"};
  std::string config_path, lcm_url, backend, log_level;
  std::vector<std::string> env_paths, client_flags;
  double eps = -1, delta = -1, status_period = -1;
  int workers = 0, gpu_device = -2;
  bool require_hardware = false;
  app.add_option("--config", config_path, "YAML configuration (see deploy/sweptccd.yaml)");
  app.add_option("--lcm-url", lcm_url, "LCM provider URL (overrides lcm_url)");
  app.add_option("--env", env_paths, "Mesh file; repeat (replaces 'environment')");
  app.add_option("--client", client_flags,
                 "ID=SKELETON.json: one more client (articulated, no filter); repeat");
  app.add_option("--eps", eps, "Time tolerance, seconds");
  app.add_option("--delta", delta, "Distance tolerance, metres");
  app.add_option("--workers", workers, "Worker threads")->check(CLI::Range(1, 1024));
  app.add_option("--backend", backend,
                 "cpu, gpu or auto (auto: the GPU on a hardware EGL device, else the CPU)");
  app.add_option("--gpu-device", gpu_device, "EGL device index for the GPU backend");
  app.add_flag("--require-hardware", require_hardware,
               "GPU backend: refuse software renderers (llvmpipe)");
  app.add_option("--status-period", status_period, "Seconds between status messages")
      ->check(CLI::Range(0.001, 3600.0));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off");
  std::string pose_channel, contact_channel, reject_channel, status_channel;
  std::vector<std::string> filter_flags, ignore_flags;
  app.add_option("--pose-channel", pose_channel, "Channel of tracker_pose_t (in)");
  app.add_option("--contact-channel", contact_channel, "Channel of contact_event_t (out)");
  app.add_option("--reject-channel", reject_channel, "Channel of rejection_t (out)");
  app.add_option("--status-channel", status_channel, "Channel of status_t (out)");
  app.add_option("--filter", filter_flags, "ID=FILTER.json: a client's collision filter; repeat");
  app.add_option("--ignore", ignore_flags,
                 "ID=LINK:OBJECT: a client ignores LINK against OBJECT (names, indices or *); "
                 "repeat");
  std::string security_mode, room_key, service_key;
  std::vector<std::string> client_key_flags;
  app.add_option("--security-mode", security_mode,
                 "signed (default) or unsigned (lab bench: nothing is authenticated)");
  app.add_option("--room-key", room_key, "Key file (mode 600, 64 hex digits) of the room");
  app.add_option("--service-key", service_key, "Key file that signs what the service publishes");
  app.add_option("--client-key", client_key_flags, "ID=FILE: a client's own key file; repeat");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "error: sweptccd-service: %s\n", e.what());
    return 2;
  }

  try {
    ServiceConfig config = config_path.empty() ? ServiceConfig() : LoadServiceConfig(config_path);
    if (!lcm_url.empty()) config.lcm_url = lcm_url;
    if (!env_paths.empty()) config.environment = env_paths;
    for (const std::string& flag : client_flags) {
      const size_t eq = flag.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == flag.size()) {
        throw InputError("--client '" + flag + "': expected ID=SKELETON.json");
      }
      ClientSpec spec;
      spec.id = flag.substr(0, eq);
      spec.skeleton_path = flag.substr(eq + 1);
      config.clients.push_back(spec);
    }
    auto split = [](const std::string& flag, const char* name) {
      const size_t eq = flag.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == flag.size()) {
        throw InputError(std::string(name) + " '" + flag + "': expected ID=VALUE");
      }
      return std::make_pair(flag.substr(0, eq), flag.substr(eq + 1));
    };
    auto client_named = [&](const std::string& id, const char* name) -> ClientSpec& {
      for (ClientSpec& c : config.clients) {
        if (c.id == id) return c;
      }
      throw InputError(std::string(name) + ": unknown client '" + id + "'");
    };
    for (const std::string& flag : filter_flags) {
      const auto [id, path] = split(flag, "--filter");
      client_named(id, "--filter").filter_path = path;
    }
    for (const std::string& flag : ignore_flags) {
      const auto [id, rule] = split(flag, "--ignore");
      client_named(id, "--ignore").ignore_rules.push_back(rule);
    }
    if (!pose_channel.empty()) config.channels.pose = pose_channel;
    if (!contact_channel.empty()) config.channels.contact = contact_channel;
    if (!reject_channel.empty()) config.channels.reject = reject_channel;
    if (!status_channel.empty()) config.channels.status = status_channel;
    if (eps >= 0) config.query.eps_s = eps;
    if (delta >= 0) config.query.delta_m = delta;
    if (workers != 0) config.workers = workers;
    if (!backend.empty()) config.backend = backend;
    if (gpu_device != -2) config.gpu_device = gpu_device;
    if (require_hardware) config.require_hardware = true;
    if (status_period >= 0) config.status_period_s = status_period;
    if (!log_level.empty()) config.log_level = log_level;
    if (!security_mode.empty()) config.security.mode = security_mode;
    if (!room_key.empty()) config.security.room_key = room_key;
    if (!service_key.empty()) config.security.service_key = service_key;
    for (const std::string& flag : client_key_flags) {
      const auto [id, path] = split(flag, "--client-key");
      config.security.client_keys[id] = path;
    }
    ValidateServiceConfig(config);
    TransportSecurity security = LoadTransportSecurity(config.security);
    const auto level = spdlog::level::from_str(config.log_level);
    if (level == spdlog::level::off && config.log_level != "off") {
      throw InputError("configuration: unknown log_level '" + config.log_level + "'");
    }
    spdlog::set_level(level);

    const auto t0 = std::chrono::steady_clock::now();
    auto env = std::make_shared<Environment>(Environment::LoadFiles(
        config.environment, MeshLoadOptions{config.max_mesh_bytes, kDefaultMaxMeshLineBytes}));
    spdlog::info("environment: {} objects, {} triangles, loaded in {:.3f} s", env->num_objects(),
                 env->num_triangles(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    std::vector<ClientConfig> clients;
    for (const ClientSpec& spec : config.clients) {
      ClientConfig cc;
      cc.client_id = spec.id;
      cc.skeleton = std::make_shared<const Skeleton>(LoadSkeletonFile(spec.skeleton_path, config.max_links));
      cc.motion = spec.motion;
      cc.filter = CollisionFilter(cc.skeleton->num_links(), env->num_objects());
      if (!spec.filter_path.empty()) {
        cc.filter = CollisionFilter::FromFile(spec.filter_path, *cc.skeleton, *env);
      }
      for (const std::string& rule : spec.ignore_rules) cc.filter.AddRule(rule, *cc.skeleton, *env);
      clients.push_back(std::move(cc));
    }
    // No pose may claim more links than the largest configured skeleton.
    security.limits.max_links = 1;
    for (const ClientConfig& cc : clients) {
      security.limits.max_links = std::max(security.limits.max_links, cc.skeleton->num_links());
    }
    // One headless context for the daemon's life; the environment is uploaded
    // once and every client's engine tests against it.
    gpu::BackendOptions backend_options;
    backend_options.backend = config.backend;
    backend_options.device_index = config.gpu_device;
    backend_options.require_hardware = config.require_hardware;
    gpu::Backend query_backend(backend_options);
    if (config.backend == "gpu" && !query_backend.gpu()) {
      spdlog::error("backend {}", query_backend.reason());
    } else {
      spdlog::info("backend {}", query_backend.reason());
    }

    lcm::LCM lcm(config.lcm_url);
    if (!lcm.good()) throw InputError("--lcm-url '" + config.lcm_url + "': LCM cannot open it");
    if (!security.signed_mode) {
      spdlog::warn("UNSIGNED MODE: poses are not authenticated and what this service publishes is "
                   "not signed; anyone on the network can forge or replay them. Lab bench only.");
    }
    LcmTransport transport(&lcm, config.channels, std::move(security));
    ServiceOptions options;
    options.num_workers = config.workers;
    options.query = config.query;
    options.backend = query_backend.name();
    options.backend_state = [&query_backend] { return query_backend.State(); };
    options.renderer = query_backend.renderer();
    options.prepare_engine = [&query_backend](CcdEngine* engine) { query_backend.Attach(engine); };
    options.security = config.security.mode;
    options.max_utime_jump_us = static_cast<int64_t>(config.security.max_utime_jump_s * 1e6);
    CollisionService service(env, std::move(clients), options, &transport);
    transport.Subscribe(&service);

    if (pipe(g_signal_pipe) != 0) throw InputError("cannot create the signal pipe");
    struct sigaction action {};
    action.sa_handler = OnSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
    spdlog::info("ready: {} clients, {} workers, listening on '{}' channel {}", config.clients.size(),
                 config.workers, config.lcm_url, config.channels.pose);

    const auto period = std::chrono::duration<double>(config.status_period_s);
    auto next_status = std::chrono::steady_clock::now() + period;
    for (;;) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= next_status) {
        service.PublishStatus();
        next_status += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
        if (next_status < now) next_status = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
        continue;
      }
      const int timeout_ms = static_cast<int>(
          std::chrono::duration_cast<std::chrono::milliseconds>(next_status - now).count() + 1);
      pollfd fds[2] = {{lcm.getFileno(), POLLIN, 0}, {g_signal_pipe[0], POLLIN, 0}};
      const int ready = poll(fds, 2, timeout_ms);
      if (ready < 0) {
        if (errno == EINTR) continue;
        throw InputError("poll failed");
      }
      if (fds[1].revents & POLLIN) break;
      if (fds[0].revents & POLLIN) lcm.handleTimeout(0);
    }
    spdlog::info("shutting down: finishing in-flight work");
    transport.Unsubscribe();
    service.Stop();
    service.PublishStatus();
    spdlog::info("stopped");
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
