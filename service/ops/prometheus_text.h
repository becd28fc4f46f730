#pragma once
// The Prometheus text exposition format 0.0.4, written directly (no
// prometheus-cpp: the daemon's counters live in status_t already, and its
// HTTP server would be a second one beside the door's Boost.Beast).
// https://prometheus.io/docs/instrumenting/exposition_formats/
// One family per name: # HELP and # TYPE once, then its samples.

#include <string>
#include <utility>
#include <vector>

#include "service/ops/latency_histogram.h"
#include "sweptccd/status_t.hpp"

namespace sweptccd {

using MetricLabels = std::vector<std::pair<std::string, std::string>>;

/// The content type a scrape answer carries.
inline constexpr const char* kPrometheusContentType = "text/plain; version=0.0.4; charset=utf-8";

/// A label value escaped as the format asks (\\, \", \n).
std::string EscapeLabelValue(const std::string& value);

/// A sample value: integers exactly, NaN and infinities as the format writes them.
std::string FormatSampleValue(double value);

class PrometheusText {
 public:
  /// Starts a family: `type` is counter, gauge or histogram.
  void Family(const std::string& name, const std::string& type, const std::string& help);
  /// One sample of the current family (a histogram's _bucket/_sum/_count
  /// are written by Histogram()).
  void Sample(const std::string& name, const MetricLabels& labels, double value);
  void Histogram(const std::string& name, const MetricLabels& labels, const LatencyHistogram& h);
  const std::string& text() const { return text_; }

 private:
  std::string text_;
};

/// Every metric of one room: the status_t counters (per client labelled
/// client, per room labelled room) and the room's pair latency histogram.
std::string RenderRoomMetrics(const std::string& room, const status_t& status,
                              const LatencyHistogram& latency);

}  // namespace sweptccd
