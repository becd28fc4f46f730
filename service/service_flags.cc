#include "service/service_flags.h"

#include <CLI/CLI.hpp>
#include <utility>

#include "core/errors.h"
#include "core/gpu/backend.h"

namespace sweptccd {

namespace {

// ID=VALUE, both parts non-empty; `flag` names the flag in errors.
std::pair<std::string, std::string> SplitIdValue(const std::string& text, const char* flag,
                                                 const char* value_name) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    throw InputError(std::string(flag) + " '" + text + "': expected ID=" + value_name);
  }
  return {text.substr(0, eq), text.substr(eq + 1)};
}

ClientSpec& ClientNamed(ServiceConfig* config, const std::string& id, const char* flag) {
  for (ClientSpec& c : config->clients) {
    if (c.id == id) return c;
  }
  throw InputError(std::string(flag) + ": unknown client '" + id + "'");
}

void ApplyClientFlags(const ServiceFlags& flags, ServiceConfig* config) {
  for (const std::string& flag : flags.client_flags) {
    ClientSpec spec;
    std::tie(spec.id, spec.skeleton_path) = SplitIdValue(flag, "--client", "SKELETON.json");
    config->clients.push_back(spec);
  }
  for (const std::string& flag : flags.filter_flags) {
    const auto [id, path] = SplitIdValue(flag, "--filter", "VALUE");
    ClientNamed(config, id, "--filter").filter_path = path;
  }
  for (const std::string& flag : flags.ignore_flags) {
    const auto [id, rule] = SplitIdValue(flag, "--ignore", "VALUE");
    ClientNamed(config, id, "--ignore").ignore_rules.push_back(rule);
  }
}

void SetIfGiven(const std::string& flag, std::string* value) {
  if (!flag.empty()) *value = flag;
}

}  // namespace

void AddServiceFlags(CLI::App* app, ServiceFlags* f) {
  app->add_option("--config", f->config_path, "YAML configuration (see deploy/sweptccd.yaml)");
  app->add_option("--lcm-url", f->lcm_url, "LCM provider URL (overrides lcm_url)");
  app->add_option("--env", f->env_paths, "Mesh file; repeat (replaces 'environment')");
  app->add_option("--client", f->client_flags,
                  "ID=SKELETON.json: one more client (articulated, no filter); repeat");
  app->add_option("--eps", f->eps_s, "Time tolerance, seconds");
  app->add_option("--delta", f->delta_m, "Distance tolerance, metres");
  app->add_option("--workers", f->workers, "Worker threads")->check(CLI::Range(1, 1024));
  app->add_option("--backend", f->backend,
                  "cpu, gpu or auto (auto: the faster on a calibration at start)");
  app->add_option("--gpu-device", f->gpu_device, "EGL device index for the GPU backend");
  app->add_flag("--require-hardware", f->require_hardware,
                "GPU backend: refuse software renderers (llvmpipe)");
  app->add_flag("--device-descent", f->device_descent,
                "GPU backend: gather the ready pairs of all clients and clear their free time "
                "intervals on the GPU in one batch (docs/SERVICE.md)");
  app->add_option("--descent-max-batch", f->descent_max_batch,
                  "Device descent: pairs per batch at most")
      ->check(CLI::Range(1, 4096));
  app->add_option("--descent-gather-us", f->descent_gather_us,
                  "Device descent: how long a worker may wait for more pairs, us (0: never)")
      ->check(CLI::Range(int64_t{0}, int64_t{100000}));
  app->add_option("--status-period", f->status_period_s, "Seconds between status messages")
      ->check(CLI::Range(0.001, 3600.0));
  app->add_option("--max-pose-rate", f->max_pose_rate_hz,
                  "Input rate limit per client, Hz (poses beyond it are shed and counted)")
      ->check(CLI::Range(0.001, 1e6));
  app->add_option("--max-object-pose-rate", f->max_object_pose_rate_hz,
                  "Input rate limit per tracked object, Hz (object poses beyond it are shed "
                  "and counted)")
      ->check(CLI::Range(0.001, 1e6));
  app->add_option("--max-live-clients", f->max_live_clients,
                  "Live clients (joined over LCM) at most at once; 0 refuses joins")
      ->check(CLI::Range(0, 4096));
  app->add_option("--silence-timeout-ms", f->silence_timeout_ms,
                  "A live client silent this long (ms) is dropped")
      ->check(CLI::Range(int64_t{10}, int64_t{3'600'000}));
  app->add_option("--log-level", f->log_level, "trace, debug, info, warn, error or off");
  app->add_option("--pose-channel", f->pose_channel, "Channel of tracker_pose_t (in)");
  app->add_option("--contact-channel", f->contact_channel, "Channel of contact_event_t (out)");
  app->add_option("--reject-channel", f->reject_channel, "Channel of rejection_t (out)");
  app->add_option("--status-channel", f->status_channel, "Channel of status_t (out)");
  app->add_option("--filter", f->filter_flags,
                  "ID=FILTER.json: a client's collision filter; repeat");
  app->add_option("--ignore", f->ignore_flags,
                  "ID=LINK:OBJECT: a client ignores LINK against OBJECT (names, indices or *); "
                  "repeat");
  app->add_option("--security-mode", f->security_mode,
                  "signed (default) or unsigned (lab bench: nothing is authenticated)");
  app->add_option("--room-key", f->room_key, "Key file (mode 600, 64 hex digits) of the room");
  app->add_option("--service-key", f->service_key,
                  "Key file that signs what the service publishes");
  app->add_option("--client-key", f->client_key_flags, "ID=FILE: a client's own key file; repeat");
  app->add_option("--ws-listen", f->ws_listen,
                  "HOST:PORT of the WebSocket door (docs/WEBSOCKET.md); off when not given");
  app->add_option("--ws-cert", f->ws_cert, "PEM certificate chain of the door (wss://)");
  app->add_option("--ws-key", f->ws_key, "PEM private key of --ws-cert");
  app->add_option("--ws-allow-origin", f->ws_allow_origins,
                  "A browser Origin allowed at the door besides its own; repeat");
  app->add_option("--ws-metrics-token-file", f->ws_metrics_token_file,
                  "Bearer token file (mode 600) that opens GET /metrics at the door");
  app->add_option("--ws-view-dir", f->ws_view_dir,
                  "Folder of the live view's files served at the door's root");
  app->add_option("--ws-max-connections", f->ws_max_connections,
                  "WebSocket/HTTP connections at most at once")
      ->check(CLI::Range(1, 65536));
  app->add_option("--ws-max-connections-per-address", f->ws_max_connections_per_address,
                  "Connections at most from one source address")
      ->check(CLI::Range(1, 65536));
  app->add_option("--room", f->room, "The room's name: the room label of every metric");
  app->add_option("--metrics-listen", f->metrics_listen,
                  "Loopback HOST:PORT of the Prometheus endpoint (GET /metrics); off when not "
                  "given");
  app->add_flag("--agones", f->agones,
                "Run as an Agones GameServer through the SDK sidecar (AGONES_SDK_HTTP_PORT)");
  app->add_option("--agones-empty-shutdown", f->agones_empty_shutdown_s,
                  "Seconds without a live client before Agones Shutdown; 0: never");
}

void ApplyServiceFlags(const ServiceFlags& flags, ServiceConfig* config) {
  SetIfGiven(flags.lcm_url, &config->lcm_url);
  if (!flags.env_paths.empty()) config->environment = flags.env_paths;
  ApplyClientFlags(flags, config);
  SetIfGiven(flags.pose_channel, &config->channels.pose);
  SetIfGiven(flags.contact_channel, &config->channels.contact);
  SetIfGiven(flags.reject_channel, &config->channels.reject);
  SetIfGiven(flags.status_channel, &config->channels.status);
  if (flags.eps_s >= 0) config->query.eps_s = flags.eps_s;
  if (flags.delta_m >= 0) config->query.delta_m = flags.delta_m;
  if (flags.workers != 0) config->workers = flags.workers;
  if (flags.max_live_clients >= 0) config->max_live_clients = flags.max_live_clients;
  if (flags.silence_timeout_ms >= 0) config->silence_timeout_ms = flags.silence_timeout_ms;
  if (!flags.backend.empty()) config->backend = gpu::ParseBackendKind(flags.backend, "--backend");
  if (flags.gpu_device != -2) config->gpu_device = flags.gpu_device;
  if (flags.require_hardware) config->require_hardware = true;
  if (flags.device_descent) config->device_descent = true;
  if (flags.descent_max_batch != 0) config->descent_max_batch = flags.descent_max_batch;
  if (flags.descent_gather_us >= 0) config->descent_gather_us = flags.descent_gather_us;
  if (flags.status_period_s >= 0) config->status_period_s = flags.status_period_s;
  if (flags.max_pose_rate_hz >= 0) config->max_pose_rate_hz = flags.max_pose_rate_hz;
  if (flags.max_object_pose_rate_hz >= 0) {
    config->max_object_pose_rate_hz = flags.max_object_pose_rate_hz;
  }
  SetIfGiven(flags.log_level, &config->log_level);
  SetIfGiven(flags.security_mode, &config->security.mode);
  SetIfGiven(flags.room_key, &config->security.room_key);
  SetIfGiven(flags.service_key, &config->security.service_key);
  for (const std::string& flag : flags.client_key_flags) {
    const size_t eq = flag.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == flag.size()) {
      throw InputError("--client-key '" + flag + "': expected ID=FILE");
    }
    config->security.client_keys[flag.substr(0, eq)] = flag.substr(eq + 1);
  }
  SetIfGiven(flags.room, &config->ops.room);
  SetIfGiven(flags.metrics_listen, &config->ops.metrics.listen);
  if (flags.agones) config->ops.agones.enabled = true;
  if (flags.agones_empty_shutdown_s >= 0) {
    config->ops.agones.empty_shutdown_s = flags.agones_empty_shutdown_s;
  }
  WsDoorOptions& ws = config->websocket;
  SetIfGiven(flags.ws_listen, &ws.listen);
  SetIfGiven(flags.ws_cert, &ws.cert_path);
  SetIfGiven(flags.ws_key, &ws.key_path);
  SetIfGiven(flags.ws_view_dir, &ws.view_dir);
  SetIfGiven(flags.ws_metrics_token_file, &ws.metrics_token_path);
  for (const std::string& o : flags.ws_allow_origins) ws.allow_origins.push_back(o);
  if (flags.ws_max_connections > 0) ws.max_connections = flags.ws_max_connections;
  if (flags.ws_max_connections_per_address > 0) {
    ws.max_connections_per_address = flags.ws_max_connections_per_address;
  }
}

ServiceConfig BuildServiceConfig(const ServiceFlags& flags) {
  ServiceConfig config =
      flags.config_path.empty() ? ServiceConfig() : LoadServiceConfig(flags.config_path);
  ApplyServiceFlags(flags, &config);
  ValidateServiceConfig(config);
  return config;
}

}  // namespace sweptccd
