#include "tools/monitor_command.h"

#include <poll.h>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <exception>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/percentile.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "service/daemon/stop_signal.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd_client/live_client.h"

namespace sweptccd {
namespace {

using Clock = std::chrono::steady_clock;
// Insertion order: "type" first, as documented.
using json = nlohmann::ordered_json;

// What this monitor saw of one client.
struct ClientTally {
  int64_t events = 0, contact = 0, free = 0, invalid = 0, rejected = 0;
  int64_t skipped = 0;            // skipped_pairs_total of the newest event.
  int64_t next_pair = -1;         // The pair number expected next; -1 before the first event.
  int64_t gaps = 0;               // Events missed (pair numbers jumped over) since the first.
  std::deque<double> latency_us;  // The newest kMaxLatencies, for the median.
};

constexpr size_t kMaxLatencies = 100000;

class Monitor {
 public:
  Monitor(const MonitorCommandOptions& options, std::optional<Skeleton> skeleton,
          std::optional<MacKey> key)
      : o_(options), skeleton_(std::move(skeleton)), key_(std::move(key)) {}

  // Callbacks of the client library's DaemonConnection (called from
  // HandleReady() on the main thread), which checked the bytes, decoded and
  // verified each message against --key. Every exception is caught and counted.
  void Listen(DaemonConnection* connection) {
    connection->OnContact([this](const contact_event_t& e, bool verified) {
      Guard(o_.contact_channel, [&] { Verified(verified), Contact(e); });
    });
    connection->OnStatus([this](const status_t& s, bool verified) {
      Guard(o_.status_channel, [&] { Verified(verified), Status(s); });
    });
    connection->OnSharedContact([this](const shared_contact_t& s, bool verified) {
      Guard(o_.shared_channel, [&] { Verified(verified), Shared(s); });
    });
    connection->OnRejection([this](const rejection_t& r, bool verified) {
      Guard(o_.reject_channel, [&] { Verified(verified), Reject(r); });
    });
    connection->OnUndecodable([this](const std::string& channel, const std::string& problem) {
      ++undecodable_;
      spdlog::warn("monitor: undecodable message on {}: {}", EscapeForDisplay(channel), problem);
    });
  }

  void Listening(const std::string& url) {
    if (o_.json) {
      Emit(json{{"type", "listening"},
                {"lcm_url", url},
                {"contact_channel", o_.contact_channel},
                {"status_channel", o_.status_channel},
                {"reject_channel", o_.reject_channel},
                {"shared_channel", o_.shared_channel},
                {"verifying", key_.has_value()}});
    } else {
      Line(fmt::format("monitor: listening on {} (contact {}, status {}, reject {}, shared {})",
                       url.empty() ? "LCM's default URL" : url, o_.contact_channel,
                       o_.status_channel, o_.reject_channel, o_.shared_channel));
    }
    if (!key_) {
      spdlog::warn("monitor: no --key: nothing is verified; every message is shown UNVERIFIED");
    }
  }

  bool count_reached() const { return o_.count > 0 && contact_total_ >= o_.count; }

  void Summary(double elapsed_s) {
    int64_t events = 0, contact = 0, free = 0, invalid = 0, rejected = 0;
    for (const auto& [id, t] : tally_) {
      events += t.events;
      contact += t.contact;
      free += t.free;
      invalid += t.invalid;
      rejected += t.rejected;
      const double median =
          Percentile(std::vector<double>(t.latency_us.begin(), t.latency_us.end()), 0.5);
      if (o_.json) {
        Emit(json{{"type", "summary"},
                  {"client", id},
                  {"events", t.events},
                  {"contact", t.contact},
                  {"free", t.free},
                  {"invalid", t.invalid},
                  {"rejected", t.rejected},
                  {"skipped", t.skipped},
                  {"gaps", t.gaps},
                  {"latency_median_us", median}});
      } else {
        Line(
            fmt::format("summary {} events {} contact {} free {} invalid {} rejected {} "
                        "skipped {} gaps {} latency median {:.0f} us",
                        Name(id), t.events, t.contact, t.free, t.invalid, t.rejected, t.skipped,
                        t.gaps, median));
      }
    }
    if (o_.json) {
      Emit(json{{"type", "total"},
                {"events", events},
                {"contact", contact},
                {"free", free},
                {"invalid", invalid},
                {"rejected", rejected},
                {"status", status_messages_},
                {"undecodable", undecodable_},
                {"unverified", unverified_},
                {"elapsed_s", elapsed_s}});
    } else {
      Line(
          fmt::format("monitor: {} events ({} contact, {} free, {} invalid), {} rejections, "
                      "{} status messages, {} undecodable, {} unverified, {:.3f} s",
                      events, contact, free, invalid, rejected, status_messages_, undecodable_,
                      unverified_, elapsed_s));
    }
  }

 private:
  template <typename F>
  void Guard(const std::string& channel, F&& f) noexcept {
    try {
      f();
    } catch (const std::exception& e) {
      ++undecodable_;
      spdlog::error("monitor: message on {}: {}", channel, e.what());
    } catch (...) {
      ++undecodable_;
      spdlog::error("monitor: message on {}: unknown exception", channel);
    }
  }

  // Sets verified_ for the lines this message prints.
  void Verified(bool verified) {
    verified_ = verified;
    if (!verified_) ++unverified_;
  }

  // A line or JSON object of a message: marked when its mac did not verify.
  void Show(const std::string& line) { Line(verified_ ? line : "UNVERIFIED " + line); }
  void EmitMsg(json j) {
    j["verified"] = verified_;
    Emit(j);
  }

  // Strings come from the network: escaped, and "-" when empty.
  static std::string Name(const std::string& id) { return id.empty() ? "-" : EscapeForDisplay(id); }

  std::string LinkName(int32_t link) const {
    if (skeleton_ && link >= 0 && link < skeleton_->num_links()) return skeleton_->link(link).name;
    return std::to_string(link);
  }

  void Contact(const contact_event_t& e) {
    ClientTally& t = tally_[e.client_id];
    ++t.events;
    // The monitor may start mid-stream: gaps count from its first event.
    if (t.next_pair >= 0 && e.pair > t.next_pair) t.gaps += e.pair - t.next_pair;
    t.next_pair = e.pair + 1;
    t.skipped = e.skipped_pairs_total;
    const int64_t latency_us = e.utime - e.receive_utime;
    t.latency_us.push_back(static_cast<double>(latency_us));
    if (t.latency_us.size() > kMaxLatencies) t.latency_us.pop_front();
    const char* result = e.result == contact_event_t::RESULT_CONTACT ? "contact"
                         : e.result == contact_event_t::RESULT_FREE  ? "free"
                                                                     : "invalid";
    if (e.result == contact_event_t::RESULT_CONTACT) {
      ++t.contact;
      ++contact_total_;
    } else if (e.result == contact_event_t::RESULT_FREE) {
      ++t.free;
    } else {
      ++t.invalid;
    }
    if (e.result == contact_event_t::RESULT_FREE && !o_.all) return;

    // Witness links (first-seen order), objects and the smallest separation.
    std::vector<int32_t> links;
    std::set<int32_t> objects;
    double separation = 0;
    for (size_t i = 0; i < e.contacts.size(); ++i) {
      const contact_record_t& c = e.contacts[i];
      if (std::find(links.begin(), links.end(), c.link) == links.end()) links.push_back(c.link);
      objects.insert(c.object);
      separation = i == 0 ? c.separation : std::min(separation, c.separation);
    }
    if (o_.json) {
      json j{{"type", result},
             {"client", e.client_id},
             {"pair", e.pair},
             {"seq0", e.seq0},
             {"seq1", e.seq1},
             {"utime0", e.utime0},
             {"utime1", e.utime1},
             {"latency_us", latency_us},
             {"compute_us", e.compute_us},
             {"queue_us", e.queue_us},
             {"receive_utime", e.receive_utime},
             {"utime", e.utime},
             {"skipped_pairs_total", e.skipped_pairs_total}};
      if (e.result == contact_event_t::RESULT_CONTACT) {
        j["t_lo"] = e.t_lo;
        j["t_hi"] = e.t_hi;
        j["s_lo"] = e.s_lo;
        j["s_hi"] = e.s_hi;
        j["initially_colliding"] = e.initially_colliding;
        j["undecided"] = e.undecided;
        json contacts = json::array();
        for (const contact_record_t& c : e.contacts) {
          contacts.push_back({{"link", c.link},
                              {"link_name", LinkName(c.link)},
                              {"object", c.object},
                              {"triangle", c.triangle},
                              {"s", c.s},
                              {"separation", c.separation}});
        }
        j["contacts"] = contacts;
      }
      if (e.result == contact_event_t::RESULT_INVALID) j["error"] = e.error;
      EmitMsg(j);
      return;
    }
    const std::string head =
        fmt::format("{} {} pair {} seq {}-{}", result, Name(e.client_id), e.pair, e.seq0, e.seq1);
    const std::string timing =
        fmt::format("latency {} us compute {:.1f} us", latency_us, e.compute_us);
    if (e.result == contact_event_t::RESULT_CONTACT) {
      std::string link_list, object_list;
      for (int32_t l : links) link_list += (link_list.empty() ? "" : ",") + LinkName(l);
      for (int32_t ob : objects)
        object_list += (object_list.empty() ? "" : ",") + std::to_string(ob);
      Show(fmt::format("{} t {:.1f}..{:.1f} us links {} object {} separation {:.5f} m {}{}{}", head,
                       e.t_lo, e.t_hi, link_list.empty() ? "-" : link_list,
                       object_list.empty() ? "-" : object_list, separation, timing,
                       e.initially_colliding ? " initially_colliding" : "",
                       e.undecided ? " undecided" : ""));
    } else if (e.result == contact_event_t::RESULT_FREE) {
      Show(fmt::format("{} {}", head, timing));
    } else {
      Show(fmt::format("{} {} error: {}", head, timing, EscapeForDisplay(e.error, 1024)));
    }
  }

  // A shared-world message: the pair of one client against other clients
  // and tracked objects (docs/SERVICE.md "Shared world"), one line per
  // entry. Free entries with --all.
  void Shared(const shared_contact_t& m) {
    ++shared_messages_;
    const size_t n = std::min(m.entries.size(), static_cast<size_t>(std::max(0, m.num_entries)));
    for (size_t i = 0; i < n; ++i) SharedEntry(m, m.entries[i], i, n);
  }

  void SharedEntry(const shared_contact_t& m, const shared_entry_t& s, size_t index, size_t n) {
    const bool contact = s.result == shared_entry_t::RESULT_CONTACT;
    const bool invalid = s.result == shared_entry_t::RESULT_INVALID;
    ++shared_total_;
    if (contact) ++shared_contact_total_;
    if (!contact && !invalid && !o_.all) return;
    const char* kind = s.entity_kind == shared_entry_t::KIND_OBJECT ? "object" : "client";
    if (o_.json) {
      json j{{"type", contact   ? "shared_contact"
                      : invalid ? "shared_invalid"
                                : "shared_free"},
             {"client", m.client_id},
             {"pair", m.pair},
             {"seq0", m.seq0},
             {"seq1", m.seq1},
             {"entity", s.entity},
             {"entity_kind", kind},
             {"window", {s.t_from, s.t_to}},
             {"waited_us", s.waited_us},
             {"ended_by_timeout", static_cast<bool>(s.ended_by_timeout)},
             {"compute_us", s.compute_us},
             {"queue_us", s.queue_us},
             {"entry", index},
             {"entries_in_message", n},
             {"utime", m.utime}};
      if (contact) {
        j["t_lo"] = s.t_lo;
        j["t_hi"] = s.t_hi;
        j["initially_colliding"] = static_cast<bool>(s.initially_colliding);
        j["undecided"] = static_cast<bool>(s.undecided);
        json contacts = json::array();
        for (const entity_contact_t& c : s.contacts) {
          contacts.push_back({{"link", c.link},
                              {"other_link", c.other_link},
                              {"triangle", c.triangle},
                              {"s", c.s},
                              {"separation", c.separation}});
        }
        j["contacts"] = contacts;
      }
      if (!s.links.empty()) {
        json links = json::array();
        for (const entity_link_bracket_t& b : s.links) {
          links.push_back({{"link", b.link},
                           {"link_name", LinkName(b.link)},
                           {"t_lo", b.t_lo},
                           {"t_hi", b.t_hi},
                           {"initially_colliding", static_cast<bool>(b.initially_colliding)},
                           {"undecided", static_cast<bool>(b.undecided)}});
        }
        j["links"] = links;
      }
      if (invalid) j["error"] = s.error;
      EmitMsg(j);
      return;
    }
    std::string head = fmt::format("shared {} {} pair {} seq {}-{} with {} {} window {}..{} us",
                                   contact   ? "contact"
                                   : invalid ? "invalid"
                                             : "free",
                                   Name(m.client_id), m.pair, m.seq0, m.seq1, kind,
                                   EscapeForDisplay(s.entity), s.t_from, s.t_to);
    if (contact) {
      head += fmt::format(" t {:.1f}..{:.1f} us", s.t_lo, s.t_hi);
      if (!s.contacts.empty()) {
        const entity_contact_t& c = s.contacts[0];
        head += fmt::format(" link {} {} {} separation {:.5f} m", LinkName(c.link),
                            c.other_link >= 0 ? "other_link" : "triangle",
                            c.other_link >= 0 ? c.other_link : c.triangle, c.separation);
      }
      if (s.initially_colliding) head += " initially_colliding";
      if (s.undecided) head += " undecided";
      if (!s.links.empty()) head += fmt::format(" links {}", s.links.size());
    }
    if (invalid) head += " error: " + EscapeForDisplay(s.error, 1024);
    head += fmt::format(" waited {} us", s.waited_us);
    if (s.ended_by_timeout) head += " ended_by_timeout";
    head += fmt::format(" [entry {} of {}]", index + 1, n);
    Show(head);
  }

  void Reject(const rejection_t& r) {
    ++tally_[r.client_id].rejected;
    if (o_.json) {
      EmitMsg(json{{"type", "reject"},
                   {"client", r.client_id},
                   {"seq", r.seq},
                   {"reason", r.reason},
                   {"message", r.message},
                   {"suppressed", r.suppressed},
                   {"utime", r.utime}});
    } else {
      // The count held back since the previous published one, at the end so
      // that the fields before keep their places.
      Show(fmt::format(
          "reject {} seq {} {}: {}{}", Name(r.client_id), r.seq, EscapeForDisplay(r.reason),
          EscapeForDisplay(r.message, 1024),
          r.suppressed > 0 ? fmt::format(" [{} suppressed before]", r.suppressed) : std::string()));
    }
  }

  void Status(const status_t& s) {
    ++status_messages_;
    const size_t n = static_cast<size_t>(std::max(0, s.num_clients));
    for (size_t i = 0; i < n; ++i) {
      if (o_.json) {
        EmitMsg(json{{"type", "status"},
                     {"client", s.client_id[i]},
                     {"poses_received", s.poses_received[i]},
                     {"pairs_answered", s.pairs_answered[i]},
                     {"pairs_skipped", s.pairs_skipped[i]},
                     {"rejected", s.rejected[i]},
                     {"seq_gaps", s.seq_gaps[i]},
                     {"rate_limited", s.rate_limited[i]},
                     {"latency_median_us", s.latency_median_us[i]},
                     {"latency_p99_us", s.latency_p99_us[i]},
                     {"utime", s.utime}});
      } else {
        Show(fmt::format(
            "status {} poses {} answered {} skipped {} rejected {} seq_missing {} rate_limited {} "
            "latency median {:.0f} us p99 {:.0f} us",
            Name(s.client_id[i]), s.poses_received[i], s.pairs_answered[i], s.pairs_skipped[i],
            s.rejected[i], s.seq_gaps[i], s.rate_limited[i], s.latency_median_us[i],
            s.latency_p99_us[i]));
      }
    }
    if (o_.json) {
      EmitMsg(json{{"type", "service"},
                   {"backend", s.backend},
                   {"renderer", s.renderer},
                   {"security", s.security},
                   {"queue_depth", s.queue_depth},
                   {"dropped_total", s.dropped_total},
                   {"rejected_unattributed", s.rejected_unattributed},
                   {"rejections_suppressed", s.rejections_suppressed},
                   {"shared_messages", s.shared_messages},
                   {"shared_entries", s.shared_entries},
                   {"shared_by_timeout", s.shared_by_timeout},
                   {"shared_dropped", s.shared_dropped},
                   {"shared_overflowed", s.shared_overflowed},
                   {"shared_cleared", s.shared_cleared},
                   {"shared_pending", s.shared_pending},
                   {"shared_ready", s.shared_ready},
                   {"object_poses_received", s.object_poses_received},
                   {"object_poses_rejected", s.object_poses_rejected},
                   {"object_poses_rate_limited", s.object_poses_rate_limited},
                   {"utime", s.utime}});
    } else {
      Show(
          fmt::format("status service backend {} security {} queue {} dropped {} unattributed {} "
                      "rejections_suppressed {}",
                      EscapeForDisplay(s.backend), EscapeForDisplay(s.security), s.queue_depth,
                      s.dropped_total, s.rejected_unattributed, s.rejections_suppressed));
      Show(fmt::format(
          "status shared messages {} entries {} by_timeout {} dropped {} overflowed {} "
          "cleared {} pending {} ready {} object_poses {} rejected {} rate_limited {}",
          s.shared_messages, s.shared_entries, s.shared_by_timeout, s.shared_dropped,
          s.shared_overflowed, s.shared_cleared, s.shared_pending, s.shared_ready,
          s.object_poses_received, s.object_poses_rejected, s.object_poses_rate_limited));
    }
  }

  // Strings from the network may hold invalid UTF-8: replaced, never thrown.
  void Emit(const json& j) { Line(j.dump(-1, ' ', false, json::error_handler_t::replace)); }

  static void Line(const std::string& line) {
    std::fwrite(line.data(), 1, line.size(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }

  const MonitorCommandOptions& o_;
  std::optional<Skeleton> skeleton_;
  std::optional<MacKey> key_;                            // --key; none: nothing is verified.
  bool verified_ = false;                                // Of the message being shown.
  int64_t shared_total_ = 0, shared_contact_total_ = 0;  // Shared-world entries seen.
  int64_t shared_messages_ = 0;                          // In this many messages.
  int64_t unverified_ = 0;
  std::map<std::string, ClientTally> tally_;
  int64_t contact_total_ = 0;
  int64_t status_messages_ = 0;
  int64_t undecodable_ = 0;
};

}  // namespace

void AddMonitorOptions(CLI::App* app, MonitorCommandOptions* o) {
  app->add_option("--lcm-url", o->lcm_url, "LCM provider URL (default: LCM's default)");
  app->add_option("--contact-channel", o->contact_channel,
                  "Channel of contact_event_t (default SWEPTCCD_CONTACT)");
  app->add_option("--status-channel", o->status_channel,
                  "Channel of status_t (default SWEPTCCD_STATUS)");
  app->add_option("--reject-channel", o->reject_channel,
                  "Channel of rejection_t (default SWEPTCCD_REJECT)");
  app->add_option("--shared-channel", o->shared_channel,
                  "Channel of shared_contact_t (default SWEPTCCD_SHARED_CONTACT)");
  app->add_option("--skeleton", o->skeleton_path, "Skeleton JSON: link names instead of indices");
  app->add_option("--count", o->count, "Exit after this many contact events (default: no limit)");
  app->add_option("--timeout", o->timeout_s,
                  "Exit after this many seconds (default: until SIGINT/SIGTERM)");
  app->add_flag("--all", o->all, "Print free events too (always counted)");
  app->add_flag("--json", o->json, "One JSON object per line, with a \"type\" field");
  app->add_option("--key", o->key_path,
                  "Key file of the service (mode 600): verify every message; what does not "
                  "verify is shown UNVERIFIED (json: \"verified\": false)");
}

int RunMonitorCommand(const MonitorCommandOptions& o) {
  std::optional<Skeleton> skeleton;
  std::optional<MacKey> key;
  try {
    if (!o.key_path.empty()) key = LoadKeyFile(o.key_path);
    if (o.count < 0) throw InputError("monitor: --count must be >= 0 (0: no limit)");
    if (!(o.timeout_s >= 0) || !std::isfinite(o.timeout_s)) {
      throw InputError("monitor: --timeout must be >= 0 seconds (0: no limit)");
    }
    if (!o.skeleton_path.empty()) skeleton = LoadSkeletonFile(o.skeleton_path);
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
  DaemonConnection::Options co;
  co.lcm_url = o.lcm_url;
  co.channels.contact = o.contact_channel;
  co.channels.status = o.status_channel;
  co.channels.reject = o.reject_channel;
  co.channels.shared_contact = o.shared_channel;
  co.service_key = key;
  co.deliver_unverified = true;  // Shown, marked UNVERIFIED.
  std::unique_ptr<DaemonConnection> connection;
  try {
    connection = std::make_unique<DaemonConnection>(std::move(co));
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: monitor: --lcm-url '%s': LCM cannot open it\n", o.lcm_url.c_str());
    return 2;
  }
  StopSignal stop;
  Monitor monitor(o, std::move(skeleton), std::move(key));
  monitor.Listen(connection.get());
  monitor.Listening(o.lcm_url);

  const Clock::time_point t0 = Clock::now();
  const Clock::time_point deadline = o.timeout_s > 0
                                         ? t0 + std::chrono::duration_cast<Clock::duration>(
                                                    std::chrono::duration<double>(o.timeout_s))
                                         : Clock::time_point::max();
  while (!monitor.count_reached()) {
    int timeout_ms = -1;
    if (deadline != Clock::time_point::max()) {
      const auto left = deadline - Clock::now();
      if (left <= Clock::duration::zero()) break;
      timeout_ms =
          static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(left).count() + 1);
    }
    pollfd fds[2] = {{connection->fileno(), POLLIN, 0}, {stop.fd(), POLLIN, 0}};
    const int ready = poll(fds, 2, timeout_ms);
    if (ready < 0) {
      if (errno == EINTR) continue;
      spdlog::error("monitor: poll failed");
      break;
    }
    if (fds[1].revents & POLLIN) break;
    if (fds[0].revents & POLLIN) connection->HandleReady(0);
  }
  monitor.Summary(std::chrono::duration<double>(Clock::now() - t0).count());
  return 0;
}

}  // namespace sweptccd
