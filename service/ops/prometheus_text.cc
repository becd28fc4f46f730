#include "service/ops/prometheus_text.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace sweptccd {

std::string EscapeLabelValue(const std::string& value) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string FormatSampleValue(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  char buf[40];
  if (value == std::floor(value) && std::fabs(value) < 9007199254740992.0) {
    std::snprintf(buf, sizeof(buf), "%.0f", value);
  } else {
    // The shortest of 15 or 17 digits that reads back as `value`.
    std::snprintf(buf, sizeof(buf), "%.15g", value);
    if (std::strtod(buf, nullptr) != value) std::snprintf(buf, sizeof(buf), "%.17g", value);
  }
  return buf;
}

namespace {

std::string LabelText(const MetricLabels& labels) {
  if (labels.empty()) return "";
  std::string out = "{";
  for (size_t i = 0; i < labels.size(); ++i) {
    if (i) out += ',';
    out += labels[i].first + "=\"" + EscapeLabelValue(labels[i].second) + '"';
  }
  return out + "}";
}

}  // namespace

void PrometheusText::Family(const std::string& name, const std::string& type,
                            const std::string& help) {
  text_ += "# HELP " + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
}

void PrometheusText::Sample(const std::string& name, const MetricLabels& labels, double value) {
  text_ += name + LabelText(labels) + " " + FormatSampleValue(value) + "\n";
}

void PrometheusText::Histogram(const std::string& name, const MetricLabels& labels,
                               const LatencyHistogram& h) {
  int64_t cumulative = 0;
  for (size_t i = 0; i <= LatencyHistogram::kBoundsS.size(); ++i) {
    cumulative += h.bucket(i);
    MetricLabels with_le = labels;
    with_le.emplace_back("le", i < LatencyHistogram::kBoundsS.size()
                                   ? FormatSampleValue(LatencyHistogram::kBoundsS[i])
                                   : std::string("+Inf"));
    Sample(name + "_bucket", with_le, static_cast<double>(cumulative));
  }
  Sample(name + "_sum", labels, h.sum_s());
  Sample(name + "_count", labels, static_cast<double>(h.count()));
}

std::string RenderRoomMetrics(const std::string& room, const status_t& s,
                              const LatencyHistogram& latency) {
  PrometheusText t;
  const MetricLabels r = {{"room", room}};
  // Per client, labelled room and client.
  struct PerClient {
    const char* name;
    const char* type;
    const char* help;
    double (*value)(const status_t&, size_t);
  };
  const PerClient per_client[] = {
      {"sweptccd_poses_received_total", "counter",
       "Pose messages received for the client (incl. rejected and rate limited).",
       [](const status_t& x, size_t i) { return double(x.poses_received[i]); }},
      {"sweptccd_pairs_answered_total", "counter", "Contact events published for the client.",
       [](const status_t& x, size_t i) { return double(x.pairs_answered[i]); }},
      {"sweptccd_pairs_skipped_total", "counter", "Pairs skipped by latest-wins.",
       [](const status_t& x, size_t i) { return double(x.pairs_skipped[i]); }},
      {"sweptccd_poses_rejected_total", "counter", "Pose messages rejected.",
       [](const status_t& x, size_t i) { return double(x.rejected[i]); }},
      {"sweptccd_seq_gaps_total", "counter", "Tracker seq numbers skipped between accepted poses.",
       [](const status_t& x, size_t i) { return double(x.seq_gaps[i]); }},
      {"sweptccd_poses_rate_limited_total", "counter",
       "Poses shed by the client's input rate limit.",
       [](const status_t& x, size_t i) { return double(x.rate_limited[i]); }},
      {"sweptccd_client_latency_median_seconds", "gauge",
       "Receive to publish latency, median of the recent window.",
       [](const status_t& x, size_t i) { return x.latency_median_us[i] * 1e-6; }},
      {"sweptccd_client_latency_p99_seconds", "gauge",
       "Receive to publish latency, 99th percentile of the recent window.",
       [](const status_t& x, size_t i) { return x.latency_p99_us[i] * 1e-6; }},
  };
  const size_t n = static_cast<size_t>(s.num_clients);
  for (const PerClient& m : per_client) {
    t.Family(m.name, m.type, m.help);
    for (size_t i = 0; i < n; ++i) {
      t.Sample(m.name, {{"room", room}, {"client", s.client_id[i]}}, m.value(s, i));
    }
  }
  struct PerRoom {
    const char* name;
    const char* type;
    const char* help;
    double value;
  };
  const PerRoom per_room[] = {
      {"sweptccd_clients", "gauge", "Clients of the room now (configured and live).",
       double(s.num_clients)},
      {"sweptccd_queue_depth", "gauge", "Pairs waiting for a worker.", double(s.queue_depth)},
      {"sweptccd_pairs_dropped_total", "counter", "Pairs skipped by latest-wins, all clients.",
       double(s.dropped_total)},
      {"sweptccd_rejected_unattributed_total", "counter", "Rejections of no registered client.",
       double(s.rejected_unattributed)},
      {"sweptccd_rejections_suppressed_total", "counter",
       "Rejections not published (publication rate bound).", double(s.rejections_suppressed)},
      {"sweptccd_instance_start_seconds", "gauge",
       "This daemon run's start time (status_t.instance), Unix seconds.",
       double(s.instance) * 1e-6},
      {"sweptccd_live_joined_total", "counter", "Live sessions accepted.", double(s.live_joined)},
      {"sweptccd_live_left_total", "counter", "Live sessions ended by leave.", double(s.live_left)},
      {"sweptccd_live_expired_total", "counter", "Live sessions dropped after silence_timeout_ms.",
       double(s.live_expired)},
      {"sweptccd_shared_messages_total", "counter", "Shared-world messages published.",
       double(s.shared_messages)},
      {"sweptccd_shared_entries_total", "counter", "Shared-world entries published.",
       double(s.shared_entries)},
      {"sweptccd_shared_by_timeout_total", "counter", "Shared-world entries ended by timeout.",
       double(s.shared_by_timeout)},
      {"sweptccd_shared_dropped_total", "counter",
       "Shared-world entries dropped unanswered (workers behind).", double(s.shared_dropped)},
      {"sweptccd_shared_overflowed_total", "counter",
       "Shared-world entries cut early (too many pending).", double(s.shared_overflowed)},
      {"sweptccd_shared_cleared_total", "counter",
       "Shared-world entries cleared by the broad phase.", double(s.shared_cleared)},
      {"sweptccd_shared_pending", "gauge",
       "Shared-world entries waiting for their entity's samples.", double(s.shared_pending)},
      {"sweptccd_shared_ready", "gauge", "Shared-world entries due and waiting for a worker.",
       double(s.shared_ready)},
      {"sweptccd_object_poses_received_total", "counter",
       "Object poses decoded and verified (incl. refused).", double(s.object_poses_received)},
      {"sweptccd_object_poses_rejected_total", "counter", "Object poses refused.",
       double(s.object_poses_rejected)},
      {"sweptccd_object_poses_rate_limited_total", "counter",
       "Object poses shed by the per-object rate limit.", double(s.object_poses_rate_limited)},
  };
  for (const PerRoom& m : per_room) {
    t.Family(m.name, m.type, m.help);
    t.Sample(m.name, r, m.value);
  }
  t.Family("sweptccd_pair_latency_seconds", "histogram",
           "Receive to publish latency of every answered pair of the room, since start.");
  t.Histogram("sweptccd_pair_latency_seconds", r, latency);
  return t.text();
}

}  // namespace sweptccd
