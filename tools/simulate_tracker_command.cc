#include "tools/simulate_tracker_command.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>

#include "core/errors.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "msgs/signing.h"
#include "sweptccd/tracker_pose_t.hpp"
#include "tools/stop_signal.h"

namespace sweptccd {
namespace {

using Clock = std::chrono::steady_clock;

// One link as the file gives it: [px, py, pz, qw, qx, qy, qz], numbers only.
bool ReadLink(const nlohmann::json& l, LinkPose* out) {
  if (!l.is_array() || l.size() != 7) return false;
  double v[7];
  for (int j = 0; j < 7; ++j) {
    if (!l[j].is_number()) return false;
    v[j] = l[j].get<double>();
  }
  out->p = Eigen::Vector3d(v[0], v[1], v[2]);
  // Sent as written (not normalised): the daemon validates and normalises,
  // exactly as `sweptccd query` does with the same file.
  out->q = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
  return true;
}

// Reads a SPEC pose stream. Unlike `sweptccd query` (which reports a bad line
// as an invalid pair and goes on), a line that cannot become a message (not
// JSON, no integer utime, links not N arrays of 7 numbers) is refused here:
// the simulator exists to send what the file says. Numeric validity (zero
// quaternions, decreasing utimes) is left to the daemon to judge.
std::vector<Pose> ReadPoseStream(const std::string& path, int* num_links) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the pose stream");
  std::vector<Pose> poses;
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = path + ": line " + std::to_string(line_no) + ": ";
    nlohmann::json doc = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded()) throw InputError(where + "not a JSON object");
    if (!doc.is_object() || !doc.contains("utime") || !doc["utime"].is_number_integer()) {
      throw InputError(where + "expected {\"utime\": INTEGER, \"links\": [...]}");
    }
    const nlohmann::json& links = doc.contains("links") ? doc["links"] : nlohmann::json();
    if (!links.is_array() || links.empty())
      throw InputError(where + "\"links\" must be a non-empty array");
    if (*num_links < 0) *num_links = static_cast<int>(links.size());
    if (static_cast<int>(links.size()) != *num_links) {
      throw InputError(where + std::to_string(links.size()) + " links, expected " +
                       std::to_string(*num_links) + " (the skeleton's / the first line's count)");
    }
    Pose pose;
    pose.utime = doc["utime"].get<int64_t>();
    pose.links.resize(links.size());
    for (size_t i = 0; i < links.size(); ++i) {
      if (!ReadLink(links[i], &pose.links[i])) {
        throw InputError(where + "link " + std::to_string(i) +
                         " must be [px, py, pz, qw, qx, qy, qz] (7 numbers)");
      }
    }
    poses.push_back(std::move(pose));
  }
  if (poses.empty()) throw InputError(path + ": no poses");
  return poses;
}

void CheckOptions(const SimulateTrackerCommandOptions& o) {
  auto bad = [](const std::string& what) { throw InputError("simulate-tracker: " + what); };
  if (o.poses_path.empty() == o.bvh.bvh_path.empty()) bad("give exactly one of --poses and --bvh");
  if (!(o.speed >= 1e-6 && o.speed <= 1e6)) bad("--speed must be a factor in [1e-6, 1e6]");
  if (!(o.bvh.rate_hz >= 0) || !std::isfinite(o.bvh.rate_hz))
    bad("--rate must be a positive number of Hz");
  if (o.loops < 0) bad("--loop must be >= 0 (0: until stopped)");
  if (!(o.jitter_us >= 0) || !std::isfinite(o.jitter_us))
    bad("--jitter-us must be >= 0 microseconds");
  if (!(o.drop_p >= 0 && o.drop_p <= 1)) bad("--drop must be a probability in [0, 1]");
  if (!(o.late_p >= 0 && o.late_p <= 1)) bad("--late must be a probability in [0, 1]");
  if (!(o.duration_s >= 0) || !std::isfinite(o.duration_s))
    bad("--duration must be >= 0 seconds (0: no limit)");
  if (o.num_clients == 0 || o.num_clients < -1) bad("--clients must be >= 1");
  // Far from int64's end, so that seq and utime cannot wrap however long it runs.
  if (o.seq_start < 0 || o.seq_start > (int64_t{1} << 62)) bad("--seq-start must be in [0, 2^62]");
  if (!(std::fabs(o.bvh.utime_start) <= 4e18)) {
    bad("--utime-start must be finite, |value| <= 4e18 microseconds");
  }
  for (double v : o.spacing) {
    if (!std::isfinite(v)) bad("--spacing must be three finite numbers (metres)");
  }
  for (double v : o.bvh.offset) {
    if (!std::isfinite(v)) bad("--offset must be three finite numbers (metres)");
  }
}

std::vector<std::string> ClientIds(const SimulateTrackerCommandOptions& o) {
  std::vector<std::string> ids = o.client_ids;
  for (int i = 0; i < std::max(0, o.num_clients); ++i)
    ids.push_back(o.client_prefix + std::to_string(i));
  if (ids.empty()) ids.push_back(o.client_prefix + "0");
  std::set<std::string> seen;
  for (const std::string& id : ids) {
    if (id.empty()) throw InputError("simulate-tracker: --client: an id must not be empty");
    if (!seen.insert(id).second)
      throw InputError("simulate-tracker: --client '" + id + "' given twice");
  }
  return ids;
}

int64_t WallClockUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The per-client state of the late mechanism.
struct ClientState {
  std::string id;
  Eigen::Vector3d offset_W{0, 0, 0};
  std::optional<tracker_pose_t> held;  // A late sample waiting for the next one.
};

}  // namespace

void AddSimulateTrackerOptions(CLI::App* app, SimulateTrackerCommandOptions* o) {
  CLI::Option* poses = app->add_option("--poses", o->poses_path, "Pose stream (SPEC JSON Lines)");
  CLI::Option* bvh =
      app->add_option("--bvh", o->bvh.bvh_path, "BVH clip, imported as `sweptccd import-bvh`");
  poses->excludes(bvh);
  app->add_option("--skeleton", o->skeleton_path,
                  "Skeleton JSON: the link count every pose must have");
  app->add_option("--lcm-url", o->lcm_url, "LCM provider URL (default: LCM's default)");
  app->add_option("--channel", o->channel, "Channel of tracker_pose_t (default SWEPTCCD_POSE)");
  app->add_option("--up", o->bvh.up_axis, "BVH: up axis of the output, y (as BVH) or z")
      ->check(CLI::IsMember({'y', 'z'}))
      ->needs(bvh);
  app->add_option("--unit", o->bvh.unit_scale_m, "BVH: metres per file unit (default: detect)")
      ->needs(bvh);
  app->add_option(
      "--start", o->bvh.start_frame,
      "First frame (BVH; default skips a reference T-pose) or pose (--poses; default 0)");
  app->add_option("--frames", o->bvh.frame_count,
                  "Frames (BVH) or poses (--poses) to play (default all)");
  app->add_option("--rate", o->bvh.rate_hz,
                  "Sample rate, Hz. BVH: subsample to it (as import-bvh --rate), published at the "
                  "rate the utimes say; --poses: publish every 1/HZ s whatever the utimes "
                  "(default: the utimes' own timing)");
  app->add_option("--offset", o->bvh.offset, "x y z metres added to every position")->expected(3);
  app->add_option("--utime-start", o->bvh.utime_start, "Microseconds added to every utime");
  app->add_option("--client", o->client_ids, "Client id; repeat for several clients");
  app->add_option("--clients", o->num_clients, "N clients PREFIX0 .. PREFIX(N-1)");
  app->add_option("--client-prefix", o->client_prefix, "Id prefix for --clients (default client)");
  app->add_option("--spacing", o->spacing,
                  "x y z metres between consecutive clients (client i is moved by i times it; "
                  "default 2 0 0: side by side, x is horizontal for y-up and z-up)")
      ->expected(3);
  app->add_option("--speed", o->speed, "Playback speed factor (default 1: real time)");
  app->add_option("--loop", o->loops, "Times the stream is played (default 1; 0: until stopped)");
  app->add_option("--jitter-us", o->jitter_us,
                  "Random delay in [0, US] microseconds added to each publication time");
  app->add_option("--drop", o->drop_p, "Probability a sample (of one client) is not sent");
  app->add_option("--late", o->late_p,
                  "Probability a sample is held back and sent after the client's next one "
                  "(the daemon rejects it: non_increasing_seq)");
  app->add_option("--seed", o->seed, "Seed of the random choices (default 1)");
  app->add_option("--duration", o->duration_s, "Stop after this many seconds (default: no limit)");
  app->add_option("--seq-start", o->seq_start, "seq of the first sample (default 0)");
  app->add_flag("--rebase-utime", o->rebase_utime,
                "utimes start at the wall clock now (spacing kept) instead of the file's");
  app->add_option("--key", o->key_path,
                  "Key file (mode 600) that signs every pose; without it poses go unsigned");
  app->add_option("--session", o->session,
                  "Stream session, >= 0 (default: the wall clock in microseconds at start, so a "
                  "restarted tracker starts a new stream)");
}

int RunSimulateTrackerCommand(const SimulateTrackerCommandOptions& o) {
  std::vector<Pose> samples;
  std::vector<ClientState> clients;
  int num_links = -1;
  try {
    CheckOptions(o);
    if (!o.skeleton_path.empty()) num_links = LoadSkeletonFile(o.skeleton_path).num_links();
    if (!o.bvh.bvh_path.empty()) {
      MocapClip clip = ImportBvhClip(o.bvh);
      if (num_links >= 0 && num_links != clip.skeleton.num_links()) {
        throw InputError(o.skeleton_path + ": " + std::to_string(num_links) + " links, but " +
                         o.bvh.bvh_path + " imports as " +
                         std::to_string(clip.skeleton.num_links()));
      }
      samples = std::move(clip.poses);
    } else {
      samples = ReadPoseStream(o.poses_path, &num_links);
      // --start / --frames select poses (import-bvh's frames).
      const size_t start = o.bvh.start_frame < 0 ? 0 : static_cast<size_t>(o.bvh.start_frame);
      if (start >= samples.size()) {
        throw InputError(o.poses_path + ": --start " + std::to_string(start) + " but only " +
                         std::to_string(samples.size()) + " poses");
      }
      samples.erase(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(start));
      if (o.bvh.frame_count >= 0 && static_cast<size_t>(o.bvh.frame_count) < samples.size()) {
        samples.resize(static_cast<size_t>(o.bvh.frame_count));
      }
      if (samples.empty()) throw InputError("simulate-tracker: --frames 0 leaves no pose to send");
    }
    for (Pose& p : samples) p.utime += static_cast<int64_t>(o.bvh.utime_start);
    const std::vector<std::string> ids = ClientIds(o);
    Eigen::Vector3d offset_W(0, 0, 0), spacing_W(0, 0, 0);
    if (o.bvh.offset.size() == 3) offset_W = {o.bvh.offset[0], o.bvh.offset[1], o.bvh.offset[2]};
    if (o.spacing.size() == 3) spacing_W = {o.spacing[0], o.spacing[1], o.spacing[2]};
    for (size_t i = 0; i < ids.size(); ++i) {
      ClientState c;
      c.id = ids[i];
      c.offset_W = offset_W + static_cast<double>(i) * spacing_W;
      clients.push_back(std::move(c));
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }

  std::optional<MacKey> key;
  try {
    if (o.session < -1) throw InputError("simulate-tracker: --session must be >= 0");
    if (!o.key_path.empty()) key = LoadKeyFile(o.key_path);
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  if (!key) {
    std::fprintf(stderr, "simulate-tracker: no --key: poses are sent UNSIGNED (a daemon in signed "
                         "mode refuses them)\n");
  }
  const int64_t session = o.session >= 0 ? o.session : WallClockUtime();
  lcm::LCM lcm(o.lcm_url);
  if (!lcm.good()) {
    std::fprintf(stderr, "error: simulate-tracker: --lcm-url '%s': LCM cannot open it\n",
                 o.lcm_url.c_str());
    return 2;
  }
  StopSignal stop;

  const int64_t n = static_cast<int64_t>(samples.size());
  const int64_t first_utime = samples.front().utime;
  const int64_t interval_us =
      n > 1 ? std::max<int64_t>(1, (samples.back().utime - first_utime) / (n - 1))
            : static_cast<int64_t>(std::llround(1e6 / (o.bvh.rate_hz > 0 ? o.bvh.rate_hz : 30.0)));
  const int64_t loop_span_us = samples.back().utime - first_utime + interval_us;
  const int64_t rebase_us = o.rebase_utime ? WallClockUtime() - first_utime : 0;
  // A pose file with --rate: a fixed publication period; otherwise the utimes'.
  const bool fixed_rate = o.poses_path.empty() ? false : o.bvh.rate_hz > 0;

  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int64_t sent = 0, dropped = 0, late = 0;
  bool publish_failed = false;
  auto publish = [&](const tracker_pose_t& m) {
    const std::vector<uint8_t> bytes = EncodeSigned(m, key ? &*key : nullptr);
    if (lcm.publish(o.channel, bytes.data(), static_cast<unsigned int>(bytes.size())) != 0) {
      publish_failed = true;
    }
    ++sent;
  };

  const Clock::time_point t0 = Clock::now();
  const Clock::time_point end = o.duration_s > 0
                                    ? t0 + std::chrono::duration_cast<Clock::duration>(
                                               std::chrono::duration<double>(o.duration_s))
                                    : Clock::time_point::max();
  int64_t loops_done = 0, rounds = 0;
  bool stopped = false;
  for (int64_t loop = 0; (o.loops == 0 || loop < o.loops) && !stopped; ++loop) {
    for (int64_t k = 0; k < n && !stopped; ++k) {
      const Pose& sample = samples[static_cast<size_t>(k)];
      const int64_t utime = sample.utime + loop * loop_span_us;
      const double due_s = fixed_rate ? static_cast<double>(loop * n + k) / o.bvh.rate_hz / o.speed
                                      : static_cast<double>(utime - first_utime) * 1e-6 / o.speed;
      const double jitter_s = o.jitter_us > 0 ? unit(rng) * o.jitter_us * 1e-6 : 0.0;
      const Clock::time_point due = t0 + std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>(due_s + jitter_s));
      if (due > end) {
        stopped = true;
        break;
      }
      if (stop.WaitUntil(due)) {
        stopped = true;
        break;
      }
      ++rounds;
      for (ClientState& c : clients) {
        const bool drop = o.drop_p > 0 && unit(rng) < o.drop_p;
        const bool hold = o.late_p > 0 && unit(rng) < o.late_p;
        if (drop) {
          ++dropped;
          continue;
        }
        tracker_pose_t m;
        m.utime = utime + rebase_us;
        m.client_id = c.id;
        m.session = session;
        m.seq = o.seq_start + loop * n + k;
        m.num_links = static_cast<int32_t>(sample.links.size());
        for (const LinkPose& l : sample.links) {
          const Eigen::Vector3d p_W = l.p + c.offset_W;
          m.position.push_back({p_W.x(), p_W.y(), p_W.z()});
          m.orientation.push_back({l.q.w(), l.q.x(), l.q.y(), l.q.z()});
        }
        // At most one sample of a client is held at a time; the very last
        // sample of the run is never held (nothing would come after it).
        const bool last = (o.loops != 0 && loop == o.loops - 1 && k == n - 1);
        if (hold && !c.held && !last) {
          c.held = std::move(m);
          continue;
        }
        publish(m);
        if (c.held) {
          publish(*c.held);
          c.held.reset();
          ++late;
        }
      }
    }
    if (!stopped) ++loops_done;
  }
  // A sample still held (stopped early, or every later sample dropped): sent
  // now, after nothing newer, so the daemon accepts it: not counted as late.
  for (ClientState& c : clients) {
    if (c.held) {
      publish(*c.held);
      c.held.reset();
    }
  }
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf(
      "simulate-tracker: sent %lld, dropped %lld, late %lld (%zu clients x %lld samples, "
      "%lld loop(s), %.3f s)\n",
      static_cast<long long>(sent), static_cast<long long>(dropped), static_cast<long long>(late),
      clients.size(), static_cast<long long>(rounds), static_cast<long long>(loops_done),
      elapsed_s);
  std::fflush(stdout);
  if (publish_failed) {
    std::fprintf(stderr, "error: simulate-tracker: LCM publish on %s failed\n", o.channel.c_str());
    return 1;
  }
  return 0;
}

}  // namespace sweptccd
