#pragma once
// The daemon's command-line flags and how they override the YAML
// configuration (service/service_config.h): declared once, merged here, so
// sweptccd-service's main only parses, builds, starts and waits.

#include <string>
#include <vector>

#include "service/service_config.h"

namespace CLI {
class App;
}  // namespace CLI

namespace sweptccd {

/// The flags as given; an empty string or a negative number means "not
/// given" (the configuration's value stays).
struct ServiceFlags {
  std::string config_path;
  std::string lcm_url;
  std::vector<std::string> env_paths;     // Replace `environment` when given.
  std::vector<std::string> client_flags;  // ID=SKELETON.json, appended to `clients`.
  std::vector<std::string> filter_flags;  // ID=FILTER.json.
  std::vector<std::string> ignore_flags;  // ID=LINK:OBJECT.
  std::string pose_channel, contact_channel, reject_channel, status_channel;
  double eps_s = -1, delta_m = -1, status_period_s = -1, max_pose_rate_hz = -1;
  double max_object_pose_rate_hz = -1;
  int workers = 0;
  int max_live_clients = -1;        // -1: not given.
  int64_t silence_timeout_ms = -1;  // -1: not given.
  std::string backend;              // cpu, gpu or auto.
  int gpu_device = -2;              // -2: not given (-1 is a valid value).
  bool require_hardware = false;
  bool device_descent = false;     // --device-descent (false: not given).
  int descent_max_batch = 0;       // 0: not given.
  int64_t descent_gather_us = -1;  // -1: not given.
  std::string log_level;
  std::string security_mode, room_key, service_key;
  std::vector<std::string> client_key_flags;  // ID=FILE.
  // The WebSocket door (docs/WEBSOCKET.md); empty / -1: not given.
  std::string ws_listen, ws_cert, ws_key, ws_view_dir, ws_metrics_token_file;
  std::vector<std::string> ws_allow_origins;  // Appended to websocket.allow_origins.
  int ws_max_connections = -1, ws_max_connections_per_address = -1;
  // Operations (docs/DEPLOY.md); empty / false: not given.
  std::string room, metrics_listen;
  bool agones = false;
  double agones_empty_shutdown_s = -1;
};

/// Declares every flag of sweptccd-service on `app`, storing into `flags`
/// (which must outlive the parse).
void AddServiceFlags(CLI::App* app, ServiceFlags* flags);

/// Applies the given flags over `config`. Throws InputError naming the flag
/// and the fix: a malformed ID=VALUE, an unknown client id, a bad backend
/// name. Does not validate the result (ValidateServiceConfig does).
void ApplyServiceFlags(const ServiceFlags& flags, ServiceConfig* config);

/// The configuration the daemon runs with: `flags.config_path` loaded (or the
/// defaults), the flags applied, the result validated. Throws InputError.
ServiceConfig BuildServiceConfig(const ServiceFlags& flags);

}  // namespace sweptccd
