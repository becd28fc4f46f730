// The operator's keys (service/ops/ops_options.h): `room`, `metrics:` and
// `agones:` in YAML, the deploy example's commented blocks, the flags over
// them, and what is refused.
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>
#include <fstream>
#include <string>

#include "core/errors.h"
#include "service/service_config.h"
#include "service/service_flags.h"

namespace sweptccd {
namespace {

const char kBase[] =
    "environment: [a.ply]\nclients: [{id: a, skeleton: s.json}]\nsecurity: {room_key: r.key}\n";

ServiceConfig Parse(const std::string& extra) {
  ServiceConfig c = ParseServiceConfig(kBase + extra, "test", "/base");
  ValidateServiceConfig(c);
  return c;
}

std::string ErrorOf(const std::string& extra) {
  try {
    Parse(extra);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(OpsConfigTest, DefaultsAreOff) {
  const ServiceConfig c = Parse("");
  EXPECT_EQ(c.ops.room, "sweptccd");
  EXPECT_TRUE(c.ops.metrics.listen.empty());
  EXPECT_FALSE(c.ops.agones.enabled);
}

TEST(OpsConfigTest, DeployExampleBlocksParse) {
  std::ifstream in(SWEPTCCD_SOURCE_DIR "/deploy/sweptccd.yaml");
  std::string line, block;
  bool inside = false;
  while (std::getline(in, line)) {
    if (line == "# metrics:") inside = true;
    if (line.rfind("# The WebSocket door", 0) == 0) inside = false;
    if (inside && line.rfind("#   ", 0) == 0) block += line.substr(2) + "\n";
    if (inside && (line == "# metrics:" || line == "# agones:")) block += line.substr(2) + "\n";
  }
  const ServiceConfig c = Parse(block);
  EXPECT_EQ(c.ops.metrics.listen, "127.0.0.1:9464");
  EXPECT_FALSE(c.ops.agones.enabled);
  EXPECT_EQ(c.ops.agones.health_period_s, 2);
  EXPECT_EQ(c.ops.agones.empty_shutdown_s, 300);
}

TEST(OpsConfigTest, KeysAndFlags) {
  ServiceConfig c = Parse(
      "room: arcade-7\nmetrics: {listen: \"[::1]:9100\"}\n"
      "agones: {enabled: true, health_period_s: 0.5, empty_shutdown_s: 0}\n");
  EXPECT_EQ(c.ops.room, "arcade-7");
  EXPECT_EQ(c.ops.metrics.listen, "[::1]:9100");
  EXPECT_TRUE(c.ops.agones.enabled);
  EXPECT_EQ(c.ops.agones.health_period_s, 0.5);
  EXPECT_EQ(c.ops.agones.empty_shutdown_s, 0);

  CLI::App app;
  ServiceFlags flags;
  AddServiceFlags(&app, &flags);
  app.parse(std::vector<std::string>{"40", "--agones-empty-shutdown", "--agones", "127.0.0.1:9200",
                                     "--metrics-listen", "r2", "--room"});
  ServiceConfig d = Parse("");
  ApplyServiceFlags(flags, &d);
  EXPECT_EQ(d.ops.room, "r2");
  EXPECT_EQ(d.ops.metrics.listen, "127.0.0.1:9200");
  EXPECT_TRUE(d.ops.agones.enabled);
  EXPECT_EQ(d.ops.agones.empty_shutdown_s, 40);
}

TEST(OpsConfigTest, RefusesWhatCannotWork) {
  EXPECT_NE(ErrorOf("metrics: {listen: \"0.0.0.0:9464\"}\n").find("loopback"), std::string::npos);
  EXPECT_NE(ErrorOf("metrics: {listen: \"10.0.0.2:9464\"}\n").find("metrics.listen"),
            std::string::npos);
  EXPECT_NE(ErrorOf("metrics: {port: 1}\n").find("port"), std::string::npos);
  EXPECT_NE(ErrorOf("agones: {health_period_s: 0}\n").find("health_period_s"), std::string::npos);
  EXPECT_NE(ErrorOf("agones: {empty_shutdown_s: -1}\n").find("empty_shutdown_s"),
            std::string::npos);
  EXPECT_NE(ErrorOf("agones: {enabled: maybe}\n").find("agones.enabled"), std::string::npos);
  EXPECT_NE(ErrorOf("room: \"a b\"\n").find("id rule"), std::string::npos);
}

}  // namespace
}  // namespace sweptccd
