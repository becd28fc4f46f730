#pragma once
// The daemon's configuration: a YAML file (deploy/sweptccd.yaml documents
// every key) with command-line overrides. Typed options, validated at load.

#include <map>
#include <string>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/query/ccd_query.h"
#include "service/lcm_transport.h"
#include "service/ops/ops_options.h"
#include "service/ws/door_options.h"

namespace sweptccd {

/// One shared-world filter of a client (SPEC 8 "Filters"), as written:
/// `{link: L, entity: ID[, other_link: M]}`. L and M are link names, "*",
/// or indices (a name first, then an index); resolved against the
/// skeletons when the daemon loads (daemon.cc, ResolveEntityRules).
struct EntityRuleSpec {
  std::string link;
  std::string entity;
  std::string other_link;  // Empty: none given (every link of ID).
};

struct ClientSpec {
  std::string id;
  std::string skeleton_path;
  MotionModel motion = MotionModel::kArticulated;
  std::string filter_path;                      // Optional collision filter JSON.
  std::vector<std::string> ignore_rules;        // LINK:OBJECT, as `sweptccd query --ignore`.
  std::vector<EntityRuleSpec> ignore_entities;  // The shared world's filters.
};

/// A tracked object (SPEC section 8; docs/SERVICE.md "Shared world"):
/// configured, never joined. Its poses come as object_pose_t.
struct ObjectSpec {
  std::string id;         // Id rule; unique across clients and objects.
  std::string mesh_path;  // One mesh file (SPEC 4), in the object's frame.
  std::string key_path;   // Optional: its key (else the room key), as client_keys.
};

/// The `security:` block (docs/SERVICE.md, "Signed messages").
struct SecurityConfig {
  std::string mode = "signed";  // signed, or unsigned for a lab bench.
  std::string room_key;         // Key file: clients without their own key, and the service.
  std::string service_key;      // Key file that signs what the service publishes; default room_key.
  std::map<std::string, std::string> client_keys;  // Client id -> key file.
  double max_utime_jump_s = 10;                    // utime_jump horizon, seconds, > 0.
};

struct ServiceConfig {
  std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0";
  LcmChannels channels;
  std::vector<std::string> environment;  // Mesh files, in object order.
  QueryOptions query;
  gpu::BackendKind backend = gpu::BackendKind::kAuto;
  int gpu_device = -1;            // EGL device index; -1: the first that works.
  bool require_hardware = false;  // gpu: refuse software renderers.
  int workers = 2;
  /// The device descent (docs/SERVICE.md "The device descent"): with the
  /// GPU backend chosen, the workers gather the ready pairs of all clients
  /// (up to descent_max_batch, 1-4096; waiting at most descent_gather_us for
  /// more, 0-100000, 0: never) and the GPU clears their environment parts'
  /// free intervals in one batch; the CPU answers (the same answers). Off
  /// by default; ignored (logged) when the backend is the CPU.
  bool device_descent = false;
  int descent_max_batch = 16;
  int64_t descent_gather_us = 0;
  double status_period_s = 1.0;
  double max_pose_rate_hz = 240;         // Input rate limit per client, Hz, in (0, 1e6].
  double max_object_pose_rate_hz = 240;  // Input rate limit per tracked object, Hz, (0, 1e6].
  std::string log_level = "info";
  uint64_t max_mesh_bytes =
      kDefaultMaxMeshBytes;          // Cap on each mesh file, before and after gunzip.
  int max_links = kDefaultMaxLinks;  // Cap on each client's skeleton.
  /// Live clients (joined over LCM, docs/SERVICE.md "Live clients") at most at
  /// once; 0 refuses every join.
  int max_live_clients = 32;
  /// How long a party may stay silent before the daemon forgets it, ms: a live
  /// client without a pose for this long is dropped (leave by silence). One
  /// setting for every silence rule of the daemon.
  int64_t silence_timeout_ms = 5000;
  std::vector<ClientSpec> clients;
  /// The shared world (docs/SERVICE.md "Shared world"): pairs answered
  /// against every other client and tracked object too. Its windows end by
  /// silence_timeout_ms (no timeout of its own). Off by default: with N
  /// co-located clients it publishes N-1 messages per pair on the bus.
  bool shared_world = false;
  std::vector<ObjectSpec> objects;
  SecurityConfig security;
  /// The WebSocket door (docs/WEBSOCKET.md), off unless websocket.listen.
  WsDoorOptions websocket;
  /// The room's name, metrics and Agones (docs/DEPLOY.md): keys `room`,
  /// `metrics:`, `agones:`.
  OpsOptions ops;
};

/// Reads a YAML configuration. Relative paths are taken relative to the
/// file's folder. Throws InputError("PATH: key: problem").
ServiceConfig LoadServiceConfig(const std::string& path);

/// Parses YAML text (`source` names it in errors; `base_dir` resolves
/// relative paths). Throws InputError.
ServiceConfig ParseServiceConfig(const std::string& text, const std::string& source,
                                 const std::string& base_dir);

/// Checks a configuration after overrides: environment and clients present,
/// unique client ids, workers >= 1, status period > 0, query options valid,
/// client ids following the id rule, the security
/// block (mode, a key for every client and for the service in signed mode).
/// Throws InputError naming the problem.
void ValidateServiceConfig(const ServiceConfig& config);

/// Loads the key files named in `security` (LoadKeyFile's checks: mode 600,
/// 64 hex digits). Unsigned mode loads nothing. Throws InputError.
TransportSecurity LoadTransportSecurity(const SecurityConfig& security);

}  // namespace sweptccd
