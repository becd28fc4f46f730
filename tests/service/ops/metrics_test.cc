// The Prometheus text (service/ops/prometheus_text.h) of a daemon on memq://
// (in-process, no network): parsed by a strict reader of the exposition
// format 0.0.4 written here (HELP and TYPE before a family's samples, one
// family per name, label syntax, counters named _total, histogram buckets
// increasing in le and in count, +Inf equal to _count), and every value
// equal to the daemon's status_t and latency histogram.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "service/collision_service.h"
#include "service/daemon/daemon.h"
#include "service/ops/latency_histogram.h"
#include "service/ops/prometheus_text.h"
#include "tests/service/service_test_util.h"

namespace sweptccd {
namespace {

// A parsed exposition: sample "name{l1="v1",...}" (labels as written) -> value.
struct Exposition {
  std::map<std::string, std::string> types;  // Family -> type.
  std::map<std::string, double> samples;
};

double ParseValue(const std::string& s) {
  if (s == "+Inf") return INFINITY;
  if (s == "-Inf") return -INFINITY;
  if (s == "NaN") return NAN;
  size_t used = 0;
  const double v = std::stod(s, &used);
  EXPECT_EQ(used, s.size()) << "value '" << s << "'";
  return v;
}

// The family a sample name belongs to (histogram suffixes stripped when the
// family is a histogram).
std::string FamilyOf(const std::string& name, const std::map<std::string, std::string>& types) {
  for (const char* suffix : {"_bucket", "_sum", "_count"}) {
    const std::string s(suffix);
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) {
      const std::string base = name.substr(0, name.size() - s.size());
      const auto it = types.find(base);
      if (it != types.end() && it->second == "histogram") return base;
    }
  }
  return name;
}

Exposition ParseStrict(const std::string& text) {
  static const std::regex help(R"(# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) (.*))");
  static const std::regex type(R"(# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram))");
  static const std::regex sample(
      R"(([a-zA-Z_:][a-zA-Z0-9_:]*)(\{([a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*")(,[a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*")*\})? (\S+))");
  Exposition e;
  std::set<std::string> helped, finished;
  std::string current;
  EXPECT_TRUE(!text.empty() && text.back() == '\n') << "the text ends with a newline";
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_match(line, m, help)) {
      EXPECT_TRUE(helped.insert(m[1]).second) << "HELP twice: " << line;
      if (!current.empty()) finished.insert(current);
      current = m[1];
      EXPECT_EQ(finished.count(current), 0u) << "family split: " << line;
    } else if (std::regex_match(line, m, type)) {
      EXPECT_EQ(m[1].str(), current) << "TYPE without its HELP first: " << line;
      EXPECT_EQ(e.types.count(m[1]), 0u) << "TYPE twice: " << line;
      e.types[m[1]] = m[2];
      if (m[2] == "counter") {
        EXPECT_TRUE(std::regex_search(m[1].str(), std::regex("_total$"))) << line;
      }
    } else if (std::regex_match(line, m, sample)) {
      EXPECT_EQ(FamilyOf(m[1], e.types), current) << "sample outside its family: " << line;
      const std::string key = m[1].str() + m[2].str();
      EXPECT_EQ(e.samples.count(key), 0u) << "sample twice: " << line;
      e.samples[key] = ParseValue(m[7]);
    } else {
      ADD_FAILURE() << "not exposition format 0.0.4: '" << line << "'";
    }
  }
  return e;
}

TEST(PrometheusTextTest, EscapesLabelValuesAndFormatsValues) {
  EXPECT_EQ(EscapeLabelValue("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
  EXPECT_EQ(FormatSampleValue(12345678901234.0), "12345678901234");
  EXPECT_EQ(FormatSampleValue(0.25), "0.25");
  EXPECT_EQ(FormatSampleValue(INFINITY), "+Inf");
  EXPECT_EQ(FormatSampleValue(NAN), "NaN");
  PrometheusText t;
  t.Family("x_total", "counter", "help");
  t.Sample("x_total", {{"room", "q\"\\\n"}}, 3);
  const Exposition e = ParseStrict(t.text());
  EXPECT_EQ(e.samples.at("x_total{room=\"q\\\"\\\\\\n\"}"), 3);
}

TEST(PrometheusTextTest, HistogramBucketsAreUpperInclusive) {
  LatencyHistogram h;
  h.ObserveMicros(50);   // le 5e-05 exactly.
  h.ObserveMicros(51);   // Next bucket.
  h.ObserveMicros(2e6);  // +Inf.
  h.ObserveMicros(-1);   // As 0.
  h.ObserveMicros(NAN);  // As 0.
  EXPECT_EQ(h.bucket(0), 3);
  EXPECT_EQ(h.bucket(1), 1);
  EXPECT_EQ(h.bucket(LatencyHistogram::kBoundsS.size()), 1);
  EXPECT_EQ(h.count(), 5);
  EXPECT_DOUBLE_EQ(h.sum_s(), 50e-6 + 51e-6 + 2.0);
}

TEST(PrometheusTextTest, DaemonMetricsParseAndEqualItsStatus) {
  const std::string dir = test::TestDir("metrics_test");
  ServiceConfig config;
  config.lcm_url = "memq://";
  config.environment = {test::WriteFloorObj(dir)};
  const std::string skeleton = test::WriteTwoLinkSkeleton(dir);
  for (const char* id : {"a", "b"}) {
    ClientSpec spec;
    spec.id = id;
    spec.skeleton_path = skeleton;
    config.clients.push_back(spec);
  }
  config.backend = gpu::BackendKind::kCpu;
  config.status_period_s = 3600;
  config.log_level = "warn";
  config.security.mode = "unsigned";
  ValidateServiceConfig(config);
  Daemon daemon(config);
  daemon.Start();
  constexpr int kPoses = 12;
  for (int64_t k = 0; k < kPoses; ++k) {
    for (const char* id : {"a", "b"}) {
      const tracker_pose_t m = test::Sample(id, k);
      daemon.lcm()->publish(kPoseChannel, &m);
    }
    if (k % 3 != 2) daemon.WaitUntilIdle();
  }
  const tracker_pose_t stranger = test::Sample("nobody", 0);
  daemon.lcm()->publish(kPoseChannel, &stranger);
  daemon.WaitUntilIdle();

  const CollisionService& service = *daemon.service();
  const status_t s = service.Status();
  const LatencyHistogram h = service.latency_histogram();
  const Exposition e = ParseStrict(RenderRoomMetrics("room-1", s, h));
  daemon.Stop();

  ASSERT_EQ(s.num_clients, 2);
  int64_t answered = 0;
  for (int i = 0; i < s.num_clients; ++i) {
    const std::string l = "{room=\"room-1\",client=\"" + s.client_id[i] + "\"}";
    EXPECT_EQ(e.samples.at("sweptccd_poses_received_total" + l), s.poses_received[i]);
    EXPECT_EQ(e.samples.at("sweptccd_pairs_answered_total" + l), s.pairs_answered[i]);
    EXPECT_EQ(e.samples.at("sweptccd_pairs_skipped_total" + l), s.pairs_skipped[i]);
    EXPECT_EQ(e.samples.at("sweptccd_poses_rejected_total" + l), s.rejected[i]);
    EXPECT_EQ(e.samples.at("sweptccd_poses_rate_limited_total" + l), s.rate_limited[i]);
    EXPECT_EQ(e.samples.at("sweptccd_seq_gaps_total" + l), s.seq_gaps[i]);
    EXPECT_DOUBLE_EQ(e.samples.at("sweptccd_client_latency_p99_seconds" + l),
                     s.latency_p99_us[i] * 1e-6);
    EXPECT_EQ(s.poses_received[i], kPoses);
    answered += s.pairs_answered[i];
  }
  EXPECT_GT(answered, 0);
  const std::string r = "{room=\"room-1\"}";
  EXPECT_EQ(e.samples.at("sweptccd_rejected_unattributed_total" + r), s.rejected_unattributed);
  EXPECT_EQ(s.rejected_unattributed, 1);
  EXPECT_EQ(e.samples.at("sweptccd_queue_depth" + r), s.queue_depth);
  EXPECT_EQ(e.samples.at("sweptccd_live_joined_total" + r), s.live_joined);
  EXPECT_EQ(e.samples.at("sweptccd_shared_entries_total" + r), s.shared_entries);
  EXPECT_EQ(e.samples.at("sweptccd_object_poses_received_total" + r), s.object_poses_received);
  EXPECT_DOUBLE_EQ(e.samples.at("sweptccd_instance_start_seconds" + r), s.instance * 1e-6);
  // The histogram: every answered pair once, buckets cumulative, +Inf = count.
  EXPECT_EQ(e.types.at("sweptccd_pair_latency_seconds"), "histogram");
  EXPECT_EQ(e.samples.at("sweptccd_pair_latency_seconds_count" + r), answered);
  EXPECT_EQ(h.count(), answered);
  double previous = 0;
  for (double le : LatencyHistogram::kBoundsS) {
    const double v = e.samples.at("sweptccd_pair_latency_seconds_bucket{room=\"room-1\",le=\"" +
                                  FormatSampleValue(le) + "\"}");
    EXPECT_GE(v, previous);
    previous = v;
  }
  EXPECT_EQ(e.samples.at("sweptccd_pair_latency_seconds_bucket{room=\"room-1\",le=\"+Inf\"}"),
            answered);
  EXPECT_GT(e.samples.at("sweptccd_pair_latency_seconds_sum" + r), 0);
}

}  // namespace
}  // namespace sweptccd
