// sweptccd-service's flags over the YAML configuration: what each overrides,
// what is left alone, and refusals that name the flag.
#include "service/service_flags.h"

#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include "core/errors.h"

namespace sweptccd {
namespace {

void ExpectRefused(const ServiceFlags& flags, ServiceConfig config, const std::string& needle) {
  try {
    ApplyServiceFlags(flags, &config);
    ADD_FAILURE() << "accepted; expected a refusal naming '" << needle << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(ServiceFlagsTest, ParsedFlagsOverrideOnlyWhatIsGiven) {
  CLI::App app;
  ServiceFlags flags;
  AddServiceFlags(&app, &flags);
  const char* argv[] = {"sweptccd-service",
                        "--lcm-url",
                        "memq://",
                        "--client",
                        "a=a.json",
                        "--client",
                        "b=b.json",
                        "--filter",
                        "b=f.json",
                        "--ignore",
                        "a=arm:*",
                        "--eps",
                        "1e-5",
                        "--backend",
                        "cpu",
                        "--gpu-device",
                        "-1",
                        "--workers",
                        "3",
                        "--room-key",
                        "room.key",
                        "--client-key",
                        "a=a.key",
                        "--max-pose-rate",
                        "500",
                        "--max-object-pose-rate",
                        "60",
                        "--device-descent",
                        "--descent-gather-us",
                        "0"};
  app.parse(static_cast<int>(std::size(argv)), argv);
  ServiceConfig config;
  config.environment = {"room.ply"};
  ClientSpec from_file;
  from_file.id = "yaml";
  from_file.skeleton_path = "y.json";
  config.clients.push_back(from_file);
  config.gpu_device = 2;
  ApplyServiceFlags(flags, &config);
  EXPECT_EQ(config.lcm_url, "memq://");
  EXPECT_EQ(config.environment, std::vector<std::string>{"room.ply"});  // Not given: kept.
  ASSERT_EQ(config.clients.size(), 3u);  // Appended to the file's clients.
  EXPECT_EQ(config.clients[1].id, "a");
  EXPECT_EQ(config.clients[1].skeleton_path, "a.json");
  EXPECT_EQ(config.clients[1].ignore_rules, std::vector<std::string>{"arm:*"});
  EXPECT_EQ(config.clients[2].filter_path, "f.json");
  EXPECT_EQ(config.query.eps_s, 1e-5);
  EXPECT_EQ(config.query.delta_m, QueryOptions{}.delta_m);
  EXPECT_EQ(config.backend, gpu::BackendKind::kCpu);
  EXPECT_EQ(config.gpu_device, -1);  // -1 is a value, not "not given".
  EXPECT_EQ(config.workers, 3);
  EXPECT_EQ(config.log_level, "info");
  EXPECT_EQ(config.max_pose_rate_hz, 500);
  EXPECT_EQ(config.max_object_pose_rate_hz, 60);
  EXPECT_TRUE(config.device_descent);
  EXPECT_EQ(config.descent_max_batch, 16);    // Not given: kept.
  EXPECT_EQ(config.descent_gather_us, 0);     // 0 is a value, not "not given".
  EXPECT_EQ(config.security.mode, "signed");  // The default: not given.
  EXPECT_EQ(config.security.room_key, "room.key");
  EXPECT_EQ(config.security.client_keys.at("a"), "a.key");
  EXPECT_NO_THROW(ValidateServiceConfig(config));
}

TEST(ServiceFlagsTest, WebsocketFlags) {
  CLI::App app;
  ServiceFlags flags;
  AddServiceFlags(&app, &flags);
  const char* argv[] = {"sweptccd-service",
                        "--ws-listen",
                        "0.0.0.0:8765",
                        "--ws-cert",
                        "c.pem",
                        "--ws-key",
                        "k.pem",
                        "--ws-allow-origin",
                        "https://a.example",
                        "--ws-allow-origin",
                        "https://b.example",
                        "--ws-view-dir",
                        "v",
                        "--ws-max-connections",
                        "9",
                        "--ws-max-connections-per-address",
                        "3",
                        "--ws-metrics-token-file",
                        "m.token"};
  app.parse(static_cast<int>(std::size(argv)), argv);
  ServiceConfig config;
  config.websocket.allow_origins = {"https://yaml.example"};
  config.websocket.handshake_timeout_ms = 1234;
  ApplyServiceFlags(flags, &config);
  const WsDoorOptions& w = config.websocket;
  EXPECT_EQ(w.listen, "0.0.0.0:8765");
  EXPECT_EQ(w.cert_path, "c.pem");
  EXPECT_EQ(w.key_path, "k.pem");
  EXPECT_EQ(w.view_dir, "v");
  EXPECT_EQ(w.metrics_token_path, "m.token");
  EXPECT_EQ(w.allow_origins, (std::vector<std::string>{"https://yaml.example", "https://a.example",
                                                       "https://b.example"}));
  EXPECT_EQ(w.max_connections, 9);
  EXPECT_EQ(w.max_connections_per_address, 3);
  EXPECT_EQ(w.handshake_timeout_ms, 1234);  // Not given: kept.
  // Not given at all: the door stays off.
  CLI::App app2;
  ServiceFlags none;
  AddServiceFlags(&app2, &none);
  const char* argv2[] = {"sweptccd-service"};
  app2.parse(1, argv2);
  ServiceConfig off;
  ApplyServiceFlags(none, &off);
  EXPECT_TRUE(off.websocket.listen.empty());
  EXPECT_TRUE(off.websocket.metrics_token_path.empty());
}

TEST(ServiceFlagsTest, RefusalsNameTheFlag) {
  ServiceConfig config;
  ServiceFlags f;
  f.client_flags = {"novalue="};
  ExpectRefused(f, config, "--client 'novalue='");
  f = {};
  f.client_flags = {"a=a.json"};
  f.filter_flags = {"b=f.json"};
  ExpectRefused(f, config, "--filter: unknown client 'b'");
  f.filter_flags = {};
  f.ignore_flags = {"a"};
  ExpectRefused(f, config, "--ignore 'a'");
  f = {};
  f.backend = "tpu";
  ExpectRefused(f, config, "--backend must be cpu, gpu or auto, got 'tpu'");
}

TEST(ServiceFlagsTest, BuildValidatesTheMergedConfiguration) {
  ServiceFlags flags;
  EXPECT_THROW(BuildServiceConfig(flags), InputError);  // No environment, no clients.
  flags.env_paths = {"room.ply"};
  flags.client_flags = {"a=a.json"};
  EXPECT_THROW(BuildServiceConfig(flags), InputError);  // Signed mode without a key.
  flags.security_mode = "unsigned";
  const ServiceConfig config = BuildServiceConfig(flags);
  EXPECT_EQ(config.clients.size(), 1u);
  EXPECT_EQ(config.backend, gpu::BackendKind::kAuto);
}

}  // namespace
}  // namespace sweptccd
