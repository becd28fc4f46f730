// The daemon's YAML configuration: a full file, relative paths, overrides'
// validation, and every refusal naming the key and the problem.

#include "service/service_config.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/errors.h"

namespace sweptccd {
namespace {

std::string RefusalOf(const std::string& yaml) {
  try {
    ValidateServiceConfig(ParseServiceConfig(yaml, "cfg.yaml", "/base"));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

const char* kFull = R"(
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
channels: {pose: P, contact: C, reject: R, status: S}
environment: [room.ply, /abs/dragon.ply.gz]
query: {eps: 2.0e-4, delta: 0.002, per_link: true, max_intervals: 5000}
backend: cpu
workers: 3
status_period_s: 0.5
max_pose_rate_hz: 150
max_object_pose_rate_hz: 75
log_level: debug
clients:
  - id: alice
    skeleton: alice.json
    motion: independent
    filter: feet.json
    ignore: ["foot_l:0", "*:1"]
  - id: bob
    skeleton: /abs/bob.json
security: {room_key: room.key}
)";

TEST(ServiceConfigTest, FullFileParses) {
  const ServiceConfig c = ParseServiceConfig(kFull, "cfg.yaml", "/base");
  EXPECT_EQ(c.lcm_url, "udpm://239.255.76.67:7667?ttl=0");
  EXPECT_EQ(c.channels.pose, "P");
  EXPECT_EQ(c.channels.contact, "C");
  EXPECT_EQ(c.channels.reject, "R");
  EXPECT_EQ(c.channels.status, "S");
  ASSERT_EQ(c.environment.size(), 2u);
  EXPECT_EQ(c.environment[0], "/base/room.ply");  // Relative to the file's folder.
  EXPECT_EQ(c.environment[1], "/abs/dragon.ply.gz");
  EXPECT_DOUBLE_EQ(c.query.eps_s, 2e-4);
  EXPECT_DOUBLE_EQ(c.query.delta_m, 0.002);
  EXPECT_TRUE(c.query.per_link);
  EXPECT_EQ(c.query.max_intervals, 5000);
  EXPECT_EQ(c.workers, 3);
  EXPECT_DOUBLE_EQ(c.status_period_s, 0.5);
  EXPECT_DOUBLE_EQ(c.max_pose_rate_hz, 150);
  EXPECT_DOUBLE_EQ(c.max_object_pose_rate_hz, 75);
  EXPECT_EQ(c.log_level, "debug");
  ASSERT_EQ(c.clients.size(), 2u);
  EXPECT_EQ(c.clients[0].id, "alice");
  EXPECT_EQ(c.clients[0].skeleton_path, "/base/alice.json");
  EXPECT_EQ(c.clients[0].motion, MotionModel::kIndependent);
  EXPECT_EQ(c.clients[0].filter_path, "/base/feet.json");
  EXPECT_EQ(c.clients[0].ignore_rules, (std::vector<std::string>{"foot_l:0", "*:1"}));
  EXPECT_EQ(c.clients[1].motion, MotionModel::kArticulated);
  EXPECT_NO_THROW(ValidateServiceConfig(c));
}

TEST(ServiceConfigTest, RefusalsNameTheKeyAndTheProblem) {
  const std::string base =
      "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}]\nsecurity: {room_key: r.key}\n";
  EXPECT_EQ(RefusalOf(base), "");
  struct Case {
    std::string yaml, must_contain;
  };
  const std::vector<Case> cases = {
      {"[not, a, map]", "mapping"},
      {"key: [unclosed", "not valid YAML"},
      {base + "colour: red\n", "unknown key 'colour'"},
      {base + "workers: many\n", "workers: expected a number"},
      {base + "workers: 0\n", "workers must be >= 1"},
      {base + "backend: tpu\n", "backend must be cpu, gpu or auto"},
      {base + "gpu_device: -5\n", "gpu_device must be an EGL device index"},
      {base + "status_period_s: 0\n", "status_period_s must be > 0"},
      {base + "max_pose_rate_hz: 0\n", "max_pose_rate_hz must be in (0, 1e6] Hz"},
      {base + "max_object_pose_rate_hz: 0\n", "max_object_pose_rate_hz must be in (0, 1e6] Hz"},
      {base + "max_object_pose_rate_hz: 2e6\n", "max_object_pose_rate_hz must be in (0, 1e6] Hz"},
      {base + "max_object_pose_rate_hz: fast\n", "max_object_pose_rate_hz"},
      {base + "query: {eps: 0}\n", "eps must be"},
      {base + "query: {delta: -1}\n", "delta must be"},
      {base + "query: {speed: 1}\n", "query: unknown key 'speed'"},
      {base + "channels: {pose: [1, 2]}\n", "channels.pose: expected a string"},
      {"environment: [a.ply]\nclients: [{id: a}]\n", "clients[0]: missing 'skeleton'"},
      {"environment: [a.ply]\nclients: [{skeleton: s}]\n", "clients[0]: missing 'id'"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s, motion: linear}]\n",
       "clients[0].motion: must be articulated or independent"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}, {id: a, skeleton: t}]\n",
       "duplicate client id 'a'"},
      {"clients: [{id: a, skeleton: s}]\n", "no environment"},
      {"environment: [a.ply]\nmax_live_clients: 0\n", "no clients and max_live_clients is 0"},
      {base + "max_live_clients: -1\n", "max_live_clients must be in [0, 4096]"},
      {base + "silence_timeout_ms: 5\n", "silence_timeout_ms must be in [10, 3600000] ms"},
      {base + "channels: {joins: X}\n", "channels: unknown key 'joins'"},
      {"environment: a.ply\nclients: [{id: a, skeleton: s}]\n", "environment: expected a list"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\n",
       "signed mode needs security.room_key or security.service_key"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\nsecurity: {service_key: k}\n",
       "client 'a' has no key"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\nsecurity: {mode: open}\n",
       "security.mode must be signed or unsigned"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\n"
       "security: {room_key: r, client_keys: {'a b': k}}\n",
       "is not a client id"},
      {"environment: [a.ply]\nclients: [{id: 'al\\nice', skeleton: s}]\n",
       "client id 'al\\\\nice' breaks the id rule"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\nsecurity: {pin: 1}\n",
       "security: unknown key 'pin'"},
      {"environment: [a.ply]\nclients: [{id: a, skeleton: s}]\n"
       "security: {room_key: r, max_utime_jump_s: 0}\n",
       "max_utime_jump_s must be in"},
  };
  for (const Case& c : cases) {
    const std::string message = RefusalOf(c.yaml);
    EXPECT_NE(message.find(c.must_contain), std::string::npos)
        << "yaml:\n"
        << c.yaml << "\nmessage: " << message;
  }
}

// Regression (tests/fuzz/corpus/fuzz_config/crash_non_scalar_key.yaml): a
// key that is a list or a mapping escaped as YAML::TypedBadConversion.
TEST(ServiceConfigTest, NonScalarKeyIsRefusedAsInputError) {
  const std::string base = "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}]\n";
  const std::vector<std::string> cases = {
      base + "? [workers, 2]\n: 3\n",
      base + "{a: b}: 1\n",
      "environment: [a.ply]\nclients: [{[id]: a, skeleton: s.json}]\n",
  };
  for (const std::string& yaml : cases) {
    const std::string message = RefusalOf(yaml);
    EXPECT_NE(message.find("a key must be a plain name"), std::string::npos)
        << "yaml:\n"
        << yaml << "\nmessage: " << message;
  }
}

TEST(ServiceConfigTest, MissingFileNamesThePath) {
  try {
    LoadServiceConfig("/nonexistent/sweptccd.yaml");
    FAIL() << "no refusal";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/sweptccd.yaml"), std::string::npos);
  }
}

// The example shipped in deploy/ must parse (its paths are examples).
TEST(ServiceConfigTest, DeployExampleParses) {
  const ServiceConfig c = LoadServiceConfig(SWEPTCCD_SOURCE_DIR "/deploy/sweptccd.yaml");
  EXPECT_FALSE(c.environment.empty());
  EXPECT_FALSE(c.clients.empty());
  EXPECT_NO_THROW(ValidateServiceConfig(c));
}

TEST(ServiceConfigTest, SecurityBlockParses) {
  const ServiceConfig c = ParseServiceConfig(
      "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}, {id: b, skeleton: s.json}]\n"
      "security:\n  mode: signed\n  service_key: svc.key\n  max_utime_jump_s: 2.5\n"
      "  client_keys: {a: a.key, b: /abs/b.key}\n",
      "test", "/base");
  EXPECT_EQ(c.security.mode, "signed");
  EXPECT_EQ(c.security.service_key, "/base/svc.key");
  EXPECT_EQ(c.security.room_key, "");
  EXPECT_EQ(c.security.client_keys.at("a"), "/base/a.key");
  EXPECT_EQ(c.security.client_keys.at("b"), "/abs/b.key");
  EXPECT_EQ(c.security.max_utime_jump_s, 2.5);
  EXPECT_NO_THROW(ValidateServiceConfig(c));
  // Unsigned mode needs no key and loads none.
  ServiceConfig bench = c;
  bench.security = SecurityConfig{};
  bench.security.mode = "unsigned";
  EXPECT_NO_THROW(ValidateServiceConfig(bench));
  EXPECT_FALSE(LoadTransportSecurity(bench.security).signed_mode);
  // Signed mode loads the files, with their checks.
  EXPECT_THROW(LoadTransportSecurity(c.security), InputError);
}

// The input limits: defaults when absent, read when given, refused when 0.
TEST(ServiceConfigTest, MaxMeshBytesAndMaxLinks) {
  const std::string base = "environment: [room.ply]\nclients: [{id: a, skeleton: a.json}]\n";
  ServiceConfig c = ParseServiceConfig(base, "cfg.yaml", "/base");
  EXPECT_EQ(c.max_mesh_bytes, kDefaultMaxMeshBytes);
  EXPECT_EQ(c.max_links, kDefaultMaxLinks);
  c = ParseServiceConfig(base + "max_mesh_bytes: 5000000000\nmax_links: 1000\n", "cfg.yaml",
                         "/base");
  EXPECT_EQ(c.max_mesh_bytes, 5000000000u);
  EXPECT_EQ(c.max_links, 1000);
  EXPECT_NE(RefusalOf(base + "max_mesh_bytes: 0\n").find("max_mesh_bytes must be >= 1"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "max_links: 0\n").find("max_links must be >= 1, got 0"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "max_links: many\n").find("cfg.yaml: max_links: expected a number"),
            std::string::npos);
}

// The device descent's settings (docs/SERVICE.md "The device descent"):
// off by default, read when given, refused out of their ranges.
TEST(ServiceConfigTest, DeviceDescentSettings) {
  const std::string base = "environment: [room.ply]\nclients: [{id: a, skeleton: a.json}]\n";
  ServiceConfig c = ParseServiceConfig(base, "cfg.yaml", "/base");
  EXPECT_FALSE(c.device_descent);
  EXPECT_EQ(c.descent_max_batch, 16);
  EXPECT_EQ(c.descent_gather_us, 0);
  c = ParseServiceConfig(
      base + "device_descent: true\ndescent_max_batch: 64\ndescent_gather_us: 2000\n", "cfg.yaml",
      "/base");
  EXPECT_TRUE(c.device_descent);
  EXPECT_EQ(c.descent_max_batch, 64);
  EXPECT_EQ(c.descent_gather_us, 2000);
  EXPECT_NE(RefusalOf(base + "descent_max_batch: 0\n")
                .find("descent_max_batch must be 1 to 4096 pairs, got 0"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "descent_max_batch: 4097\n").find("descent_max_batch"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "descent_gather_us: -1\n")
                .find("descent_gather_us must be 0 to 100000 us, got -1"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "descent_gather_us: 100001\n").find("descent_gather_us"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "device_descent: sometimes\n").find("cfg.yaml: device_descent"),
            std::string::npos);
}

// The shared world: tracked objects (id, mesh, key) and the switch.
// The shared world's filters (SPEC 8 "Filters") of a configured client:
// parsed as written (resolved against the skeletons when the daemon loads);
// every malformed rule refused with one line naming it.
TEST(ServiceConfigTest, IgnoreEntitiesParseAndBadRulesAreRefused) {
  const std::string head = R"(
environment: [room.ply]
security: {room_key: room.key}
shared_world: true
)";
  const ServiceConfig c = ParseServiceConfig(
      head +
          "clients: [{id: alice, skeleton: a.json, ignore_entities: [{link: rhand, entity: "
          "cup}, {link: \"*\", entity: bob, other_link: 3}]}]\n",
      "cfg.yaml", "/base");
  ASSERT_EQ(c.clients.size(), 1u);
  ASSERT_EQ(c.clients[0].ignore_entities.size(), 2u);
  EXPECT_EQ(c.clients[0].ignore_entities[0].link, "rhand");
  EXPECT_EQ(c.clients[0].ignore_entities[0].entity, "cup");
  EXPECT_EQ(c.clients[0].ignore_entities[0].other_link, "");
  EXPECT_EQ(c.clients[0].ignore_entities[1].link, "*");
  EXPECT_EQ(c.clients[0].ignore_entities[1].other_link, "3");
  EXPECT_NO_THROW(ValidateServiceConfig(c));
  auto with = [&](const std::string& rules) {
    return head + "clients: [{id: alice, skeleton: a.json, ignore_entities: " + rules + "}]\n";
  };
  EXPECT_NE(RefusalOf(with("{link: a, entity: b}")).find("ignore_entities: expected a list"),
            std::string::npos);
  EXPECT_NE(RefusalOf(with("[rhand]")).find("ignore_entities[0]: expected {link"),
            std::string::npos);
  EXPECT_NE(RefusalOf(with("[{link: rhand}]")).find("needs 'link' and 'entity'"),
            std::string::npos);
  EXPECT_NE(RefusalOf(with("[{link: rhand, entity: cup, colour: red}]")).find("colour"),
            std::string::npos);
  EXPECT_NE(RefusalOf(with("[{link: rhand, entity: \"bad id\"}]")).find("id rule"),
            std::string::npos);
  EXPECT_NE(RefusalOf(with("[{link: \"\", entity: cup}]")).find("not empty"), std::string::npos);
  const std::string off = R"(
environment: [room.ply]
security: {room_key: room.key}
clients: [{id: alice, skeleton: a.json, ignore_entities: [{link: rhand, entity: cup}]}]
)";
  EXPECT_NE(RefusalOf(off).find("ignore_entities, which need shared_world: true"),
            std::string::npos);
}

TEST(ServiceConfigTest, TrackedObjectsParseAndShareTheIdSpace) {
  const std::string base = R"(
environment: [room.ply]
clients: [{id: alice, skeleton: a.json}]
security: {room_key: room.key}
shared_world: true
)";
  const ServiceConfig c = ParseServiceConfig(
      base +
          "channels: {object_pose: OP, shared_contact: SC}\n"
          "objects: [{id: cup, mesh: cup.obj, key: cup.key}, {id: ball, mesh: /abs/ball.stl}]\n",
      "cfg.yaml", "/base");
  EXPECT_TRUE(c.shared_world);
  EXPECT_EQ(c.channels.object_pose, "OP");
  EXPECT_EQ(c.channels.shared_contact, "SC");
  ASSERT_EQ(c.objects.size(), 2u);
  EXPECT_EQ(c.objects[0].id, "cup");
  EXPECT_EQ(c.objects[0].mesh_path, "/base/cup.obj");
  EXPECT_EQ(c.objects[0].key_path, "/base/cup.key");
  EXPECT_EQ(c.objects[1].key_path, "");
  EXPECT_NO_THROW(ValidateServiceConfig(c));
  EXPECT_NE(RefusalOf(base + "objects: [{id: alice, mesh: m.obj}]\n").find("names two entities"),
            std::string::npos);
  EXPECT_NE(RefusalOf(base + "objects: [{id: \"bad id\", mesh: m.obj}]\n").find("id rule"),
            std::string::npos);
  // Two objects with one id (not only an object named like a client).
  EXPECT_NE(RefusalOf(base + "objects: [{id: cup, mesh: m.obj}, {id: cup, mesh: n.obj}]\n")
                .find("names two entities"),
            std::string::npos);
  const std::string off = R"(
environment: [room.ply]
clients: [{id: alice, skeleton: a.json}]
security: {room_key: room.key}
)";
  EXPECT_NE(RefusalOf(off + "objects: [{id: cup, mesh: m.obj}]\n").find("shared_world: true"),
            std::string::npos)
      << "off by default";
  EXPECT_FALSE(ParseServiceConfig(off, "cfg.yaml", "/").shared_world);
  EXPECT_NE(RefusalOf(base + "objects: [{id: cup}]\n").find("missing 'mesh'"), std::string::npos);
  EXPECT_NE(RefusalOf(base + "objects: [{id: cup, mesh: m.obj, colour: red}]\n").find("colour"),
            std::string::npos);
  const std::string no_room = R"(
environment: [room.ply]
clients: [{id: alice, skeleton: a.json}]
security: {client_keys: {alice: a.key}}
shared_world: true
objects: [{id: cup, mesh: m.obj}]
)";
  EXPECT_NE(RefusalOf(no_room).find("object 'cup' has no key"), std::string::npos);
  EXPECT_TRUE(ParseServiceConfig(base, "cfg.yaml", "/").shared_world);
}

}  // namespace
}  // namespace sweptccd

namespace sweptccd {
namespace {

// The WebSocket door's block (docs/WEBSOCKET.md): every key, relative paths
// against the file's folder, unknown keys and bad values refused; the
// --ws-* flags override it.
TEST(ServiceConfigTest, WebsocketBlockParses) {
  // The deploy example's commented block, uncommented, parses.
  std::ifstream in(SWEPTCCD_SOURCE_DIR "/deploy/sweptccd.yaml");
  std::string line, block;
  bool inside = false;
  while (std::getline(in, line)) {
    if (line == "# websocket:") inside = true;
    if (inside && line.rfind("# ", 0) == 0) block += line.substr(2) + "\n";
  }
  ASSERT_FALSE(block.empty());
  const ServiceConfig d = ParseServiceConfig(
      "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}]\nsecurity: {room_key: r.key}\n" +
          block,
      "deploy", "/base");
  EXPECT_EQ(d.websocket.listen, "127.0.0.1:8765");
  EXPECT_EQ(d.websocket.cert_path, "/etc/sweptccd/door.crt");
  EXPECT_EQ(d.websocket.allow_origins, std::vector<std::string>{"https://app.example"});
  EXPECT_EQ(d.websocket.max_scene_triangles, 200000);
  EXPECT_NO_THROW(ValidateServiceConfig(d));
  const ServiceConfig c = ParseServiceConfig(
      "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}]\nsecurity: {room_key: r.key}\n"
      "websocket: {listen: \"0.0.0.0:9000\", cert: c.pem, key: k.pem, view_dir: view,\n"
      "  max_connections: 5, max_connections_per_address: 2, handshake_timeout_ms: 700,\n"
      "  idle_timeout_ms: 900, max_message_bytes: 4096, message_rate_hz: 50, message_burst: 3,\n"
      "  send_queue_messages: 7, send_queue_bytes: 8192, socket_send_buffer_bytes: 16384,\n"
      "  max_objects_per_connection: 1, max_scene_triangles: 99, metrics_token_file: m.token}\n",
      "test", "/base");
  const WsDoorOptions& w = c.websocket;
  EXPECT_EQ(w.cert_path, "/base/c.pem");
  EXPECT_EQ(w.key_path, "/base/k.pem");
  EXPECT_EQ(w.view_dir, "/base/view");
  EXPECT_EQ(w.max_connections, 5);
  EXPECT_EQ(w.max_connections_per_address, 2);
  EXPECT_EQ(w.handshake_timeout_ms, 700);
  EXPECT_EQ(w.idle_timeout_ms, 900);
  EXPECT_EQ(w.max_message_bytes, 4096u);
  EXPECT_EQ(w.message_rate_hz, 50);
  EXPECT_EQ(w.message_burst, 3);
  EXPECT_EQ(w.send_queue_messages, 7u);
  EXPECT_EQ(w.send_queue_bytes, 8192u);
  EXPECT_EQ(w.socket_send_buffer_bytes, 16384);
  EXPECT_EQ(w.max_objects_per_connection, 1);
  EXPECT_EQ(w.max_scene_triangles, 99);
  EXPECT_EQ(w.metrics_token_path, "/base/m.token");
  EXPECT_NO_THROW(ValidateServiceConfig(c));
  EXPECT_THROW(ParseServiceConfig("websocket: {lisen: x}\n", "t", "/b"), InputError);
  ServiceConfig bad = c;
  bad.websocket.key_path.clear();
  try {
    ValidateServiceConfig(bad);
    FAIL() << "cert without key accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--ws-key"), std::string::npos);
  }
  // A metrics token off loopback without TLS: refused (a bearer token in clear).
  ServiceConfig clear = c;
  clear.websocket.cert_path.clear();
  clear.websocket.key_path.clear();
  clear.security.mode = "unsigned";
  try {
    ValidateServiceConfig(clear);
    FAIL() << "a metrics token over plain HTTP off loopback accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("metrics_token_file"), std::string::npos);
  }
  clear.websocket.listen = "127.0.0.1:9000";
  EXPECT_NO_THROW(ValidateServiceConfig(clear));
}

}  // namespace
}  // namespace sweptccd
