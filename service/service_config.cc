#include "service/service_config.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "core/errors.h"
#include "msgs/text.h"

namespace sweptccd {

namespace {

std::string Resolve(const std::string& base_dir, const std::string& path) {
  if (path.empty() || base_dir.empty() || std::filesystem::path(path).is_absolute()) return path;
  return (std::filesystem::path(base_dir) / path).string();
}

template <class T>
T Get(const YAML::Node& node, const std::string& where) {
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw InputError(where + ": expected " +
                     (std::is_same_v<T, std::string> ? std::string("a string")
                      : std::is_same_v<T, bool>      ? std::string("true or false")
                                                     : std::string("a number")) +
                     ", got '" + YAML::Dump(node) + "'");
  }
}

void CheckKeys(const YAML::Node& map, const std::set<std::string>& known,
               const std::string& where) {
  for (const auto& kv : map) {
    // A key may be any YAML node ("? [a, b]: 1"); as<std::string>() would
    // throw YAML's own exception for a non-scalar one (found by fuzz_config).
    if (!kv.first.IsScalar()) {
      throw InputError(where + ": a key must be a plain name, got '" + YAML::Dump(kv.first) + "'");
    }
    const std::string key = kv.first.Scalar();
    if (!known.count(key)) throw InputError(where + ": unknown key '" + key + "'");
  }
}

std::vector<std::string> StringList(const YAML::Node& node, const std::string& where) {
  if (!node.IsSequence()) throw InputError(where + ": expected a list");
  std::vector<std::string> out;
  for (size_t i = 0; i < node.size(); ++i) {
    out.push_back(Get<std::string>(node[i], where + "[" + std::to_string(i) + "]"));
  }
  return out;
}

SecurityConfig ParseSecurity(const YAML::Node& node, const std::string& at,
                             const std::string& base_dir) {
  if (!node.IsMap()) throw InputError(at + "security: expected a mapping");
  CheckKeys(node, {"mode", "room_key", "service_key", "client_keys", "max_utime_jump_s"},
            at + "security");
  SecurityConfig sc;
  if (node["mode"]) sc.mode = Get<std::string>(node["mode"], at + "security.mode");
  if (node["room_key"]) {
    sc.room_key = Resolve(base_dir, Get<std::string>(node["room_key"], at + "security.room_key"));
  }
  if (node["service_key"]) {
    sc.service_key =
        Resolve(base_dir, Get<std::string>(node["service_key"], at + "security.service_key"));
  }
  if (const YAML::Node keys = node["client_keys"]) {
    if (!keys.IsMap()) throw InputError(at + "security.client_keys: expected a mapping id: file");
    for (const auto& kv : keys) {
      const std::string id = Get<std::string>(kv.first, at + "security.client_keys");
      sc.client_keys[id] =
          Resolve(base_dir, Get<std::string>(kv.second, at + "security.client_keys." + id));
    }
  }
  if (node["max_utime_jump_s"]) {
    sc.max_utime_jump_s = Get<double>(node["max_utime_jump_s"], at + "security.max_utime_jump_s");
  }
  return sc;
}

void ValidateSecurity(const ServiceConfig& c) {
  const SecurityConfig& sc = c.security;
  if (sc.mode != "signed" && sc.mode != "unsigned") {
    throw InputError("configuration: security.mode must be signed or unsigned, got '" +
                     EscapeForDisplay(sc.mode) + "'");
  }
  if (!(sc.max_utime_jump_s > 0 && sc.max_utime_jump_s <= 1e6)) {
    throw InputError("configuration: security.max_utime_jump_s must be in (0, 1e6] seconds");
  }
  for (const auto& [id, path] : sc.client_keys) {
    if (!IsValidClientId(id)) {
      throw InputError("configuration: security.client_keys: '" + EscapeForDisplay(id) +
                       "' is not a client id (1-64 of A-Z a-z 0-9 _ . -)");
    }
  }
  if (sc.mode == "unsigned") return;
  if (sc.room_key.empty() && sc.service_key.empty()) {
    throw InputError(
        "configuration: signed mode needs security.room_key or security.service_key "
        "(make one with `sweptccd keygen --out FILE`), or security.mode: unsigned");
  }
  for (const ClientSpec& spec : c.clients) {
    if (sc.room_key.empty() && !sc.client_keys.count(spec.id)) {
      throw InputError("configuration: client '" + spec.id +
                       "' has no key; add it under "
                       "security.client_keys or set security.room_key");
    }
  }
}

}  // namespace

TransportSecurity LoadTransportSecurity(const SecurityConfig& sc) {
  TransportSecurity security;
  security.signed_mode = sc.mode != "unsigned";
  if (!security.signed_mode) return security;
  if (!sc.room_key.empty()) security.keys.SetRoomKey(LoadKeyFile(sc.room_key));
  if (!sc.service_key.empty()) security.keys.SetServiceKey(LoadKeyFile(sc.service_key));
  for (const auto& [id, path] : sc.client_keys) security.keys.SetClientKey(id, LoadKeyFile(path));
  return security;
}

namespace {

// channels: the channel names, each optional.
void ParseChannels(const YAML::Node& ch, const std::string& at, LcmChannels* channels) {
  if (!ch.IsMap()) throw InputError(at + "channels: expected a mapping");
  CheckKeys(ch,
            {"pose", "contact", "reject", "status", "join", "join_reply", "leave", "object_pose",
             "shared_contact"},
            at + "channels");
  if (ch["object_pose"]) {
    channels->object_pose = Get<std::string>(ch["object_pose"], at + "channels.object_pose");
  }
  if (ch["shared_contact"]) {
    channels->shared_contact =
        Get<std::string>(ch["shared_contact"], at + "channels.shared_contact");
  }
  if (ch["join"]) channels->join = Get<std::string>(ch["join"], at + "channels.join");
  if (ch["join_reply"]) {
    channels->join_reply = Get<std::string>(ch["join_reply"], at + "channels.join_reply");
  }
  if (ch["leave"]) channels->leave = Get<std::string>(ch["leave"], at + "channels.leave");
  if (ch["pose"]) channels->pose = Get<std::string>(ch["pose"], at + "channels.pose");
  if (ch["contact"]) channels->contact = Get<std::string>(ch["contact"], at + "channels.contact");
  if (ch["reject"]) channels->reject = Get<std::string>(ch["reject"], at + "channels.reject");
  if (ch["status"]) channels->status = Get<std::string>(ch["status"], at + "channels.status");
}

// query: the tolerances and the work limit.
void ParseQuery(const YAML::Node& q, const std::string& at, QueryOptions* query) {
  if (!q.IsMap()) throw InputError(at + "query: expected a mapping");
  CheckKeys(q, {"eps", "delta", "per_link", "max_intervals"}, at + "query");
  if (q["eps"]) query->eps_s = Get<double>(q["eps"], at + "query.eps");
  if (q["delta"]) query->delta_m = Get<double>(q["delta"], at + "query.delta");
  if (q["per_link"]) query->per_link = Get<bool>(q["per_link"], at + "query.per_link");
  if (q["max_intervals"]) {
    query->max_intervals = Get<int64_t>(q["max_intervals"], at + "query.max_intervals");
  }
}

// The scalar settings between `query` and `clients`, in the file's key order
// of the documentation (backend, workers, rates, limits; security among them).
void ParseSettings(const YAML::Node& root, const std::string& at, const std::string& base_dir,
                   ServiceConfig* c) {
  if (root["backend"]) {
    const std::string name = Get<std::string>(root["backend"], at + "backend");
    c->backend = gpu::ParseBackendKind(name, at + "backend");
  }
  if (root["gpu_device"]) c->gpu_device = Get<int>(root["gpu_device"], at + "gpu_device");
  if (root["require_hardware"]) {
    c->require_hardware = Get<bool>(root["require_hardware"], at + "require_hardware");
  }
  if (root["workers"]) c->workers = Get<int>(root["workers"], at + "workers");
  if (root["device_descent"]) {
    c->device_descent = Get<bool>(root["device_descent"], at + "device_descent");
  }
  if (root["descent_max_batch"]) {
    c->descent_max_batch = Get<int>(root["descent_max_batch"], at + "descent_max_batch");
  }
  if (root["descent_gather_us"]) {
    c->descent_gather_us = Get<int64_t>(root["descent_gather_us"], at + "descent_gather_us");
  }
  if (root["status_period_s"]) {
    c->status_period_s = Get<double>(root["status_period_s"], at + "status_period_s");
  }
  if (root["max_pose_rate_hz"]) {
    c->max_pose_rate_hz = Get<double>(root["max_pose_rate_hz"], at + "max_pose_rate_hz");
  }
  if (root["max_object_pose_rate_hz"]) {
    c->max_object_pose_rate_hz =
        Get<double>(root["max_object_pose_rate_hz"], at + "max_object_pose_rate_hz");
  }
  if (root["log_level"]) c->log_level = Get<std::string>(root["log_level"], at + "log_level");
  if (root["security"]) c->security = ParseSecurity(root["security"], at, base_dir);
  if (root["max_mesh_bytes"]) {
    c->max_mesh_bytes = Get<uint64_t>(root["max_mesh_bytes"], at + "max_mesh_bytes");
  }
  if (root["max_links"]) c->max_links = Get<int>(root["max_links"], at + "max_links");
  if (root["max_live_clients"]) {
    c->max_live_clients = Get<int>(root["max_live_clients"], at + "max_live_clients");
  }
  if (root["silence_timeout_ms"]) {
    c->silence_timeout_ms = Get<int64_t>(root["silence_timeout_ms"], at + "silence_timeout_ms");
  }
}

// One rule of a client's ignore_entities (`rw` names it).
EntityRuleSpec ParseEntityRule(const YAML::Node& r, const std::string& rw) {
  if (!r.IsMap()) {
    throw InputError(rw +
                     ": expected {link: L, entity: ID} or {link: L, entity: ID, "
                     "other_link: M}");
  }
  CheckKeys(r, {"link", "entity", "other_link"}, rw);
  if (!r["link"] || !r["entity"]) throw InputError(rw + ": needs 'link' and 'entity'");
  EntityRuleSpec rule;
  rule.link = Get<std::string>(r["link"], rw + ".link");
  rule.entity = Get<std::string>(r["entity"], rw + ".entity");
  if (r["other_link"]) rule.other_link = Get<std::string>(r["other_link"], rw + ".other_link");
  if (!IsValidClientId(rule.entity)) {
    throw InputError(rw + ".entity: '" + EscapeForDisplay(rule.entity) +
                     "' breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)");
  }
  if (rule.link.empty() || (r["other_link"] && rule.other_link.empty())) {
    throw InputError(rw + ": a link is a name, an index or \"*\", not empty");
  }
  return rule;
}

// One entry of `clients` (`where` names it).
ClientSpec ParseClient(const YAML::Node& e, const std::string& where, const std::string& base_dir) {
  if (!e.IsMap()) throw InputError(where + ": expected a mapping");
  CheckKeys(e, {"id", "skeleton", "motion", "filter", "ignore", "ignore_entities"}, where);
  ClientSpec spec;
  if (!e["id"]) throw InputError(where + ": missing 'id'");
  if (!e["skeleton"]) throw InputError(where + ": missing 'skeleton'");
  spec.id = Get<std::string>(e["id"], where + ".id");
  spec.skeleton_path = Resolve(base_dir, Get<std::string>(e["skeleton"], where + ".skeleton"));
  if (e["motion"]) {
    const std::string m = Get<std::string>(e["motion"], where + ".motion");
    const auto model = ParseMotionModel(m);
    if (!model) {
      throw InputError(where + ".motion: must be articulated or independent, got '" + m + "'");
    }
    spec.motion = *model;
  }
  if (e["filter"]) {
    spec.filter_path = Resolve(base_dir, Get<std::string>(e["filter"], where + ".filter"));
  }
  if (e["ignore"]) spec.ignore_rules = StringList(e["ignore"], where + ".ignore");
  if (const YAML::Node rules = e["ignore_entities"]) {
    if (!rules.IsSequence()) throw InputError(where + ".ignore_entities: expected a list");
    for (size_t k = 0; k < rules.size(); ++k) {
      spec.ignore_entities.push_back(
          ParseEntityRule(rules[k], where + ".ignore_entities[" + std::to_string(k) + "]"));
    }
  }
  return spec;
}

// One entry of `objects` (`where` names it).
ObjectSpec ParseObject(const YAML::Node& e, const std::string& where, const std::string& base_dir) {
  if (!e.IsMap()) throw InputError(where + ": expected a mapping");
  CheckKeys(e, {"id", "mesh", "key"}, where);
  if (!e["id"]) throw InputError(where + ": missing 'id'");
  if (!e["mesh"]) throw InputError(where + ": missing 'mesh'");
  ObjectSpec spec;
  spec.id = Get<std::string>(e["id"], where + ".id");
  spec.mesh_path = Resolve(base_dir, Get<std::string>(e["mesh"], where + ".mesh"));
  if (e["key"]) spec.key_path = Resolve(base_dir, Get<std::string>(e["key"], where + ".key"));
  return spec;
}

}  // namespace

// Operations (docs/DEPLOY.md): room, metrics.*, agones.*.
void ParseOperations(const YAML::Node& root, const std::string& at, ServiceConfig* config) {
  ServiceConfig& c = *config;
  if (root["room"]) c.ops.room = Get<std::string>(root["room"], at + "room");
  if (const YAML::Node m = root["metrics"]) {
    if (!m.IsMap()) throw InputError(at + "metrics: expected a mapping");
    CheckKeys(m, {"listen"}, at + "metrics");
    if (m["listen"]) c.ops.metrics.listen = Get<std::string>(m["listen"], at + "metrics.listen");
  }
  if (const YAML::Node a = root["agones"]) {
    if (!a.IsMap()) throw InputError(at + "agones: expected a mapping");
    CheckKeys(a, {"enabled", "health_period_s", "empty_shutdown_s"}, at + "agones");
    AgonesOptions& o = c.ops.agones;
    if (a["enabled"]) o.enabled = Get<bool>(a["enabled"], at + "agones.enabled");
    if (a["health_period_s"]) {
      o.health_period_s = Get<double>(a["health_period_s"], at + "agones.health_period_s");
    }
    if (a["empty_shutdown_s"]) {
      o.empty_shutdown_s = Get<double>(a["empty_shutdown_s"], at + "agones.empty_shutdown_s");
    }
  }
}

// The WebSocket door (docs/WEBSOCKET.md "Configuration"): websocket.*.
void ParseWebsocket(const YAML::Node& w, const std::string& at, const std::string& base_dir,
                    ServiceConfig* config) {
  ServiceConfig& c = *config;
  const std::string where = at + "websocket";
  if (!w.IsMap()) throw InputError(where + ": expected a mapping");
  CheckKeys(w,
            {"listen", "cert", "key", "allow_origins", "view_dir", "max_connections",
             "max_connections_per_address", "handshake_timeout_ms", "idle_timeout_ms",
             "max_message_bytes", "message_rate_hz", "message_burst", "send_queue_messages",
             "send_queue_bytes", "max_objects_per_connection", "max_scene_triangles",
             "socket_send_buffer_bytes", "metrics_token_file"},
            where);
  WsDoorOptions& o = c.websocket;
  const std::string in = where + ".";
  if (w["listen"]) o.listen = Get<std::string>(w["listen"], in + "listen");
  if (w["cert"]) o.cert_path = Resolve(base_dir, Get<std::string>(w["cert"], in + "cert"));
  if (w["key"]) o.key_path = Resolve(base_dir, Get<std::string>(w["key"], in + "key"));
  if (w["allow_origins"]) o.allow_origins = StringList(w["allow_origins"], in + "allow_origins");
  if (w["metrics_token_file"]) {
    o.metrics_token_path =
        Resolve(base_dir, Get<std::string>(w["metrics_token_file"], in + "metrics_token_file"));
  }
  if (w["view_dir"]) {
    o.view_dir = Resolve(base_dir, Get<std::string>(w["view_dir"], in + "view_dir"));
  }
  if (w["max_connections"])
    o.max_connections = Get<int>(w["max_connections"], in + "max_connections");
  if (w["max_connections_per_address"]) {
    o.max_connections_per_address =
        Get<int>(w["max_connections_per_address"], in + "max_connections_per_address");
  }
  if (w["handshake_timeout_ms"]) {
    o.handshake_timeout_ms = Get<int64_t>(w["handshake_timeout_ms"], in + "handshake_timeout_ms");
  }
  if (w["idle_timeout_ms"]) {
    o.idle_timeout_ms = Get<int64_t>(w["idle_timeout_ms"], in + "idle_timeout_ms");
  }
  if (w["max_message_bytes"]) {
    o.max_message_bytes = Get<size_t>(w["max_message_bytes"], in + "max_message_bytes");
  }
  if (w["message_rate_hz"])
    o.message_rate_hz = Get<double>(w["message_rate_hz"], in + "message_rate_hz");
  if (w["message_burst"]) o.message_burst = Get<int>(w["message_burst"], in + "message_burst");
  if (w["send_queue_messages"]) {
    o.send_queue_messages = Get<size_t>(w["send_queue_messages"], in + "send_queue_messages");
  }
  if (w["send_queue_bytes"]) {
    o.send_queue_bytes = Get<size_t>(w["send_queue_bytes"], in + "send_queue_bytes");
  }
  if (w["max_objects_per_connection"]) {
    o.max_objects_per_connection =
        Get<int>(w["max_objects_per_connection"], in + "max_objects_per_connection");
  }
  if (w["socket_send_buffer_bytes"]) {
    o.socket_send_buffer_bytes =
        Get<int>(w["socket_send_buffer_bytes"], in + "socket_send_buffer_bytes");
  }
  if (w["max_scene_triangles"]) {
    o.max_scene_triangles = Get<int>(w["max_scene_triangles"], in + "max_scene_triangles");
  }
}

ServiceConfig ParseServiceConfig(const std::string& text, const std::string& source,
                                 const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(source + ": not valid YAML (" + std::string(e.what()) + ")");
  }
  ServiceConfig c;
  if (root.IsNull()) return c;
  if (!root.IsMap()) throw InputError(source + ": the configuration must be a YAML mapping");
  CheckKeys(root,
            {"lcm_url",
             "channels",
             "environment",
             "query",
             "backend",
             "gpu_device",
             "require_hardware",
             "workers",
             "device_descent",
             "descent_max_batch",
             "descent_gather_us",
             "status_period_s",
             "log_level",
             "clients",
             "security",
             "max_mesh_bytes",
             "max_links",
             "max_pose_rate_hz",
             "max_object_pose_rate_hz",
             "max_live_clients",
             "silence_timeout_ms",
             "shared_world",
             "objects",
             "websocket",
             "room",
             "metrics",
             "agones"},
            source);
  const std::string at = source + ": ";
  if (root["lcm_url"]) c.lcm_url = Get<std::string>(root["lcm_url"], at + "lcm_url");
  if (const YAML::Node ch = root["channels"]) ParseChannels(ch, at, &c.channels);
  if (root["environment"]) {
    for (const std::string& p : StringList(root["environment"], at + "environment")) {
      c.environment.push_back(Resolve(base_dir, p));
    }
  }
  if (const YAML::Node q = root["query"]) ParseQuery(q, at, &c.query);
  ParseSettings(root, at, base_dir, &c);
  if (const YAML::Node clients = root["clients"]) {
    if (!clients.IsSequence()) throw InputError(at + "clients: expected a list");
    for (size_t i = 0; i < clients.size(); ++i) {
      c.clients.push_back(
          ParseClient(clients[i], at + "clients[" + std::to_string(i) + "]", base_dir));
    }
  }
  if (root["shared_world"]) c.shared_world = Get<bool>(root["shared_world"], at + "shared_world");
  if (const YAML::Node objects = root["objects"]) {
    if (!objects.IsSequence()) throw InputError(at + "objects: expected a list");
    for (size_t i = 0; i < objects.size(); ++i) {
      c.objects.push_back(
          ParseObject(objects[i], at + "objects[" + std::to_string(i) + "]", base_dir));
    }
  }
  ParseOperations(root, at, &c);
  if (const YAML::Node w = root["websocket"]) ParseWebsocket(w, at, base_dir, &c);
  return c;
}

ServiceConfig LoadServiceConfig(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the configuration file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseServiceConfig(buffer.str(), path, std::filesystem::path(path).parent_path().string());
}

void ValidateServiceConfig(const ServiceConfig& c) {
  if (c.environment.empty()) {
    throw InputError("configuration: no environment (give 'environment' or --env)");
  }
  if (c.clients.empty() && c.max_live_clients < 1) {
    throw InputError(
        "configuration: no clients and max_live_clients is 0 (give 'clients' or "
        "--client, or allow live clients)");
  }
  if (c.max_live_clients < 0 || c.max_live_clients > 4096) {
    throw InputError("configuration: max_live_clients must be in [0, 4096], got " +
                     std::to_string(c.max_live_clients));
  }
  if (c.silence_timeout_ms < 10 || c.silence_timeout_ms > 3'600'000) {
    throw InputError("configuration: silence_timeout_ms must be in [10, 3600000] ms, got " +
                     std::to_string(c.silence_timeout_ms));
  }
  std::set<std::string> ids;
  for (const ClientSpec& s : c.clients) {
    if (!s.ignore_entities.empty() && !c.shared_world) {
      throw InputError("configuration: client '" + EscapeForDisplay(s.id) +
                       "' has ignore_entities, which need shared_world: true");
    }
    if (!IsValidClientId(s.id)) {
      throw InputError("configuration: client id '" + EscapeForDisplay(s.id) +
                       "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
    }
    if (!ids.insert(s.id).second)
      throw InputError("configuration: duplicate client id '" + s.id + "'");
  }
  if (const std::string problem = ValidateWsDoorOptions(c.websocket); !problem.empty()) {
    throw InputError("configuration: " + problem);
  }
  for (const ObjectSpec& o : c.objects) {
    if (!IsValidClientId(o.id)) {
      throw InputError("configuration: object id '" + EscapeForDisplay(o.id) +
                       "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
    }
    if (!ids.insert(o.id).second) {
      throw InputError("configuration: id '" + o.id +
                       "' names two entities (clients and objects share one id space)");
    }
    if (!o.key_path.empty() && c.security.client_keys.count(o.id)) {
      throw InputError("configuration: object '" + o.id +
                       "' has a key and a security.client_keys entry; keep one");
    }
    if (c.security.mode != "unsigned" && o.key_path.empty() && c.security.room_key.empty() &&
        !c.security.client_keys.count(o.id)) {
      throw InputError("configuration: object '" + o.id +
                       "' has no key; give objects[].key or set security.room_key");
    }
  }
  if (const std::string problem = ValidateOpsOptions(c.ops); !problem.empty()) {
    throw InputError("configuration: " + problem);
  }
  if (!c.shared_world && !c.objects.empty()) {
    throw InputError("configuration: objects need shared_world: true");
  }
  if (c.workers < 1)
    throw InputError("configuration: workers must be >= 1, got " + std::to_string(c.workers));
  if (c.descent_max_batch < 1 || c.descent_max_batch > 4096) {
    throw InputError("configuration: descent_max_batch must be 1 to 4096 pairs, got " +
                     std::to_string(c.descent_max_batch));
  }
  if (c.descent_gather_us < 0 || c.descent_gather_us > 100000) {
    throw InputError("configuration: descent_gather_us must be 0 to 100000 us, got " +
                     std::to_string(c.descent_gather_us));
  }
  if (!(c.status_period_s > 0)) throw InputError("configuration: status_period_s must be > 0");
  if (!(c.max_pose_rate_hz > 0 && c.max_pose_rate_hz <= 1e6)) {
    throw InputError("configuration: max_pose_rate_hz must be in (0, 1e6] Hz");
  }
  if (!(c.max_object_pose_rate_hz > 0 && c.max_object_pose_rate_hz <= 1e6)) {
    throw InputError("configuration: max_object_pose_rate_hz must be in (0, 1e6] Hz");
  }
  if (c.max_mesh_bytes == 0) throw InputError("configuration: max_mesh_bytes must be >= 1 byte");
  if (c.max_links < 1) {
    throw InputError("configuration: max_links must be >= 1, got " + std::to_string(c.max_links));
  }
  if (c.gpu_device < -1) {
    throw InputError(
        "configuration: gpu_device must be an EGL device index >= 0 (or -1 for the "
        "first that works), got " +
        std::to_string(c.gpu_device));
  }
  const std::string problem = ValidateQueryOptions(c.query);
  if (!problem.empty()) throw InputError("configuration: query: " + problem);
  ValidateSecurity(c);
}

}  // namespace sweptccd
