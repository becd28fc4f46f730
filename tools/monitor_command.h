#pragma once
// `sweptccd monitor`: a live, readable view of a running sweptccd-service.
// Subscribes to contact_event_t, status_t and rejection_t and prints, one
// line each, flushed per line:
//   contact  every event whose result is contact (client, pair, seq0-seq1,
//            t_lo..t_hi, witness links and objects, smallest separation,
//            latency = event utime - receive_utime, compute time);
//   free     events whose result is free (only with --all; always counted);
//   invalid  events whose query failed (always);
//   reject   every rejection, with its reason code and message;
//   status   per client, every status_t the daemon sends (poses, answered,
//            skipped, rejected, latency median/p99), then one line for the
//            service (backend, queue depth, dropped, unattributed rejections);
//   summary  at exit, per client what this monitor saw (events by result,
//            rejections, skipped, gaps = events missed by pair number since
//            its first event, latency median), and one total line.
// Text by default; with --json one JSON object per line with a "type" field
// ("listening", "contact", "free", "invalid", "reject", "status",
// "service", "summary", "total") for scripts. The first line ("listening")
// is printed once subscribed: a script can wait for it before publishing.

#include <cstdint>
#include <string>

#include "msgs/channels.h"

namespace CLI {
class App;
}

namespace sweptccd {

struct MonitorCommandOptions {
  std::string lcm_url;  // Empty: LCM's default (LCM_DEFAULT_URL or udpm).
  std::string contact_channel = kContactChannel;
  std::string status_channel = kStatusChannel;
  std::string reject_channel = kRejectChannel;
  std::string shared_channel = kSharedContactChannel;
  std::string key_path;  // Service key file; empty: nothing is verified.
  std::string skeleton_path;  // Optional: link names instead of indices.
  int64_t count = 0;          // Exit after this many contact events; 0: no limit.
  double timeout_s = 0;       // Exit after this many seconds; 0: until SIGINT/SIGTERM.
  bool all = false;           // Print free events too.
  bool json = false;          // One JSON object per line.
};

void AddMonitorOptions(CLI::App* app, MonitorCommandOptions* options);

/// Runs until --count contact events, --timeout or SIGINT/SIGTERM, then
/// prints the summary. Returns 0 then; 2 with a one-line message on standard
/// error for bad input (flags, the skeleton file, an LCM URL LCM refuses).
/// Malformed messages are counted and reported on standard error, never fatal.
int RunMonitorCommand(const MonitorCommandOptions& options);

}  // namespace sweptccd
