#include "tools/simulate_tracker_command.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/world/world_file.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "service/daemon/stop_signal.h"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/live_client.h"
#include "sweptccd_client/tracker_pose.h"

namespace sweptccd {
namespace {

using Clock = std::chrono::steady_clock;

// Where the samples of one pass (loop) come from. Not thread-safe.
class SampleSource {
 public:
  virtual ~SampleSource() = default;
  /// Starts a pass at the first selected sample (a pose file is re-opened).
  virtual void Rewind() = 0;
  /// The next sample of this pass, or nullopt at its end.
  virtual std::optional<Pose> Next() = 0;
  /// Lines skipped in the first pass because they are no pose.
  virtual int64_t skipped() const { return 0; }
};

// A BVH clip imported in memory (bounded by the importer's own limits).
class ClipSource : public SampleSource {
 public:
  explicit ClipSource(std::vector<Pose> poses) : poses_(std::move(poses)) {}
  void Rewind() override { next_ = 0; }
  std::optional<Pose> Next() override {
    if (next_ >= poses_.size()) return std::nullopt;
    return poses_[next_++];
  }

 private:
  std::vector<Pose> poses_;
  size_t next_ = 0;
};

// A SPEC pose file streamed through the core's PoseLineReader: the same blank
// lines, line cap and utime parsing as `sweptccd query`; at most one line in
// memory. A counted line that is no pose (not JSON, a wrong link count, over
// the line cap) cannot become a message: it is skipped with a warning (the
// first kMaxWarnings of them, then only counted). Poses are sent as written
// (not normalised): the daemon validates and normalises them, exactly as
// `query` does with the same file. --start / --frames count the poses.
class PoseFileSource : public SampleSource {
 public:
  PoseFileSource(std::string path, int num_links, int64_t start, int64_t frames)
      : path_(std::move(path)),
        num_links_(num_links),
        max_line_bytes_(DefaultMaxPoseLineBytes(num_links)),
        start_(start),
        frames_(frames) {}

  void Rewind() override {
    in_ = std::make_unique<std::ifstream>(OpenInputFile(path_, "pose stream"));
    // The same cap every pass (without --skeleton: the cap for kDefaultMaxLinks).
    reader_ = std::make_unique<PoseLineReader>(*in_, num_links_, max_line_bytes_);
    returned_ = 0;
    ++pass_;
    for (int64_t k = 0; k < start_ && NextPose(); ++k) {
    }
  }

  std::optional<Pose> Next() override {
    if (frames_ >= 0 && returned_ >= frames_) return std::nullopt;
    std::optional<Pose> pose = NextPose();
    if (pose) ++returned_;
    return pose;
  }

  int64_t skipped() const override { return skipped_; }

 private:
  static constexpr int64_t kMaxWarnings = 5;

  std::optional<Pose> NextPose() {
    while (std::optional<PoseLine> line = reader_->Next()) {
      if (line->pose) {
        num_links_ = reader_->num_links();  // Fixed by the first pose without --skeleton.
        return std::move(line->pose);
      }
      if (pass_ > 1) continue;
      if (++skipped_ <= kMaxWarnings) {
        spdlog::warn("{}: {} (skipped: no pose to send{})", path_, line->error,
                     skipped_ == kMaxWarnings ? "; further skipped lines are only counted" : "");
      }
    }
    if (reader_->bad()) throw InputError(path_ + ": error while reading the pose stream");
    return std::nullopt;
  }

  std::string path_;
  int num_links_;
  uint64_t max_line_bytes_;
  int64_t start_, frames_;
  std::unique_ptr<std::ifstream> in_;
  std::unique_ptr<PoseLineReader> reader_;
  int64_t returned_ = 0, skipped_ = 0, pass_ = 0;
};

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

// --join-ignore-entity LINK:ENTITY[:OTHER_LINK]. An id has no ':' (the id
// rule), so the parts are unambiguous unless a link name holds one: then
// give its index.
EntityIgnore ParseEntityRule(const std::string& spec) {
  std::vector<std::string> parts;
  size_t from = 0;
  for (size_t colon; (colon = spec.find(':', from)) != std::string::npos; from = colon + 1) {
    parts.push_back(spec.substr(from, colon - from));
  }
  parts.push_back(spec.substr(from));
  if (parts.size() < 2 || parts.size() > 3 || parts[0].empty() || parts[1].empty() ||
      (parts.size() == 3 && parts[2].empty())) {
    throw InputError("simulate-tracker: --join-ignore-entity '" + EscapeForDisplay(spec) +
                     "': expected LINK:ENTITY or LINK:ENTITY:OTHER_LINK (a link name holding "
                     "':' is given by its index)");
  }
  return EntityIgnore{parts[0], parts[1], parts.size() == 3 ? parts[2] : ""};
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

// The per-client state of the late mechanism and of its own rate and phase.
struct ClientState {
  std::string id;
  Eigen::Vector3d offset_W{0, 0, 0};
  std::optional<tracker_pose_t> held;  // A late sample waiting for the next one.
  double rate_hz = 0;      // > 0: plays at its own rate (--client-rate); 0: every sample.
  double phase_us = 0;     // --client-phase-us.
  int64_t ticks_done = 0;  // Its ticks before this one are served.
  int64_t seq = 0;         // Its next seq (own rate: one per sent sample).

  // Whether the sample at `utime` is the one the client sends at its next
  // tick (the first sample at or after the tick); advances past it.
  bool Takes(int64_t utime, int64_t first_utime) {
    if (rate_hz <= 0) return true;
    const double period_us = 1e6 / rate_hz;
    const double since = static_cast<double>(utime - first_utime) - phase_us;
    if (since < ticks_done * period_us) return false;
    ticks_done = static_cast<int64_t>(std::floor(since / period_us)) + 1;
    return true;
  }
};

// "ID=VALUE" of --client-rate / --client-phase-us for a known client id; the
// value a finite number. Throws InputError naming the flag.
std::pair<std::string, double> ParseClientValue(const std::string& flag, const std::string& spec,
                                                const std::string& unit,
                                                const std::vector<ClientState>& clients) {
  const size_t eq = spec.find('=');
  const std::string id = eq == std::string::npos ? spec : spec.substr(0, eq);
  const bool known =
      std::any_of(clients.begin(), clients.end(), [&](const ClientState& c) { return c.id == id; });
  double v = std::nan("");
  if (eq != std::string::npos) {
    try {
      size_t used = 0;
      v = std::stod(spec.substr(eq + 1), &used);
      if (used != spec.size() - eq - 1) v = std::nan("");
    } catch (const std::exception&) {
    }
  }
  if (!known || !std::isfinite(v)) {
    throw InputError("simulate-tracker: " + flag + " '" + EscapeForDisplay(spec) +
                     "': use ID=" + unit +
                     " with ID one of the clients (--client, --clients) and " + unit + " a number");
  }
  return {id, v};
}

// Applies --client-rate and --client-phase-us. Throws InputError.
void SetClientRates(const SimulateTrackerCommandOptions& o, std::vector<ClientState>* clients) {
  auto find = [&](const std::string& id) -> ClientState& {
    return *std::find_if(clients->begin(), clients->end(),
                         [&](const ClientState& c) { return c.id == id; });
  };
  std::set<std::string> seen;
  for (const std::string& spec : o.client_rates) {
    const auto [id, hz] = ParseClientValue("--client-rate", spec, "HZ", *clients);
    if (!seen.insert(id).second) {
      throw InputError("simulate-tracker: --client-rate: client '" + id + "' given twice");
    }
    if (!(hz > 0 && hz <= 10000)) {
      throw InputError("simulate-tracker: --client-rate '" + EscapeForDisplay(spec) +
                       "': the rate must be in (0, 10000] Hz");
    }
    find(id).rate_hz = hz;
  }
  seen.clear();
  for (const std::string& spec : o.client_phases) {
    const auto [id, us] = ParseClientValue("--client-phase-us", spec, "US", *clients);
    if (!seen.insert(id).second) {
      throw InputError("simulate-tracker: --client-phase-us: client '" + id + "' given twice");
    }
    ClientState& c = find(id);
    if (c.rate_hz <= 0) {
      throw InputError("simulate-tracker: --client-phase-us '" + EscapeForDisplay(spec) +
                       "' needs --client-rate " + id + "=HZ");
    }
    if (!(us >= 0 && us < 1e6 / c.rate_hz)) {
      throw InputError("simulate-tracker: --client-phase-us '" + EscapeForDisplay(spec) +
                       "': the phase must be in [0, 1e6 / HZ) microseconds");
    }
    c.phase_us = us;
  }
}

// The seeded random choices and what they did.
struct RoundCounters {
  explicit RoundCounters(uint64_t seed) : rng(seed) {}
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> unit{0.0, 1.0};
  int64_t dropped = 0, late = 0;
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
  app->add_option("--object-channel", o->object_channel,
                  "Channel of --object's object_pose_t (default SWEPTCCD_OBJECT_POSE)");
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
  app->add_flag("--join", o->join,
                "Join as live clients (with --skeleton or the BVH clip's), leave at the end; "
                "--key is then the room key");
  app->add_option("--service-key", o->service_key_path,
                  "--join: key file that verifies the daemon's replies (default: --key)");
  app->add_option("--join-ignore", o->ignore_rules,
                  "--join: LINK:OBJECT filter rule sent with the join; repeat");
  app->add_option("--join-ignore-entity", o->entity_rules,
                  "--join: LINK:ENTITY or LINK:ENTITY:OTHER_LINK, a shared-world filter sent "
                  "with the join (SPEC 8; links by name, index or *); repeat");
  app->add_option("--object", o->objects,
                  "ID=POSES.jsonl: a tracked object's pose lines (SPEC 8), sent as object_pose_t "
                  "on --object-channel by utime among the avatars' samples; repeatable");
  app->add_option("--client-rate", o->client_rates,
                  "ID=HZ: client ID plays at HZ, taking at each of its ticks the first sample at "
                  "or after it (a subset of the stream, as is); repeatable");
  app->add_option("--client-phase-us", o->client_phases,
                  "ID=US: client ID's ticks start US microseconds after the first sample "
                  "(needs --client-rate ID=HZ; 0 <= US < 1e6/HZ); repeatable");
  app->add_option("--session", o->session,
                  "Stream session, >= 0 (default: the wall clock in microseconds at start, so a "
                  "restarted tracker starts a new stream)");
}

namespace {

// The source of the samples: a BVH clip imported whole, or a pose file
// streamed pass by pass. Throws InputError.
std::unique_ptr<SampleSource> MakeSource(const SimulateTrackerCommandOptions& o,
                                         std::optional<Skeleton>* skeleton) {
  int num_links = -1;
  if (!o.skeleton_path.empty()) {
    *skeleton = LoadSkeletonFile(o.skeleton_path);
    num_links = (*skeleton)->num_links();
  }
  if (o.bvh.bvh_path.empty()) {
    // --start / --frames select poses (import-bvh's frames).
    auto source = std::make_unique<PoseFileSource>(
        o.poses_path, num_links, std::max(0, o.bvh.start_frame), o.bvh.frame_count);
    if (o.bvh.frame_count == 0) {
      throw InputError("simulate-tracker: --frames 0 leaves no pose to send");
    }
    return source;
  }
  MocapClip clip = ImportBvhClip(o.bvh);
  if (num_links >= 0 && num_links != clip.skeleton.num_links()) {
    throw InputError(o.skeleton_path + ": " + std::to_string(num_links) + " links, but " +
                     o.bvh.bvh_path + " imports as " + std::to_string(clip.skeleton.num_links()));
  }
  if (!*skeleton) *skeleton = clip.skeleton;
  return std::make_unique<ClipSource>(std::move(clip.poses));
}

std::vector<ClientState> MakeClients(const SimulateTrackerCommandOptions& o) {
  const std::vector<std::string> ids = ClientIds(o);
  Eigen::Vector3d offset_W(0, 0, 0), spacing_W(0, 0, 0);
  if (o.bvh.offset.size() == 3) offset_W = {o.bvh.offset[0], o.bvh.offset[1], o.bvh.offset[2]};
  if (o.spacing.size() == 3) spacing_W = {o.spacing[0], o.spacing[1], o.spacing[2]};
  std::vector<ClientState> clients;
  for (size_t i = 0; i < ids.size(); ++i) {
    ClientState c;
    c.id = ids[i];
    c.offset_W = offset_W + static_cast<double>(i) * spacing_W;
    clients.push_back(std::move(c));
  }
  return clients;
}

// What the first pass learns about the stream, for the later passes.
struct StreamShape {
  int64_t n = 0;  // Samples in a pass.
  int64_t first_utime = 0, last_utime = 0;
  int64_t loop_span_us = 0;  // Added to the utimes of each later pass.
};

// Publishes one sample for every client (drop, late hold, then the held one).
// `stream_utime`: the sample's utime before rebasing (the clients' ticks).
void SendRound(const SimulateTrackerCommandOptions& o, const Pose& sample, int64_t utime,
               int64_t stream_utime, int64_t first_utime, int64_t session, int64_t seq,
               std::vector<ClientState>* clients, RoundCounters* counters,
               const std::function<void(const tracker_pose_t&)>& publish) {
  for (ClientState& c : *clients) {
    if (!c.Takes(stream_utime, first_utime)) continue;
    // Own rate: consecutive seq over the samples it sends; else the stream's.
    const int64_t client_seq = c.rate_hz > 0 ? o.seq_start + c.seq++ : seq;
    const bool drop = o.drop_p > 0 && counters->unit(counters->rng) < o.drop_p;
    const bool hold = o.late_p > 0 && counters->unit(counters->rng) < o.late_p;
    if (drop) {
      ++counters->dropped;
      continue;
    }
    tracker_pose_t m = TrackerPoseOf(sample, c.offset_W);
    m.utime = utime;
    m.client_id = c.id;
    m.session = session;
    m.seq = client_seq;
    // At most one sample of a client is held at a time. (A sample held at the
    // end of the run is sent after the last round, after nothing newer.)
    if (hold && !c.held) {
      c.held = std::move(m);
      continue;
    }
    publish(m);
    if (c.held) {
      publish(*c.held);
      c.held.reset();
      ++counters->late;
    }
  }
}

// The first pass has ended: the stream's shape fixes the later passes.
void FinishFirstPass(const SimulateTrackerCommandOptions& o, StreamShape* shape) {
  const int64_t n = shape->n;
  const int64_t interval_us =
      n > 1 ? std::max<int64_t>(1, (shape->last_utime - shape->first_utime) / (n - 1))
            : static_cast<int64_t>(std::llround(1e6 / (o.bvh.rate_hz > 0 ? o.bvh.rate_hz : 30.0)));
  shape->loop_span_us = shape->last_utime - shape->first_utime + interval_us;
}

// Plays the passes, reading each sample just before it is due (so a pose file
// is streamed: memory does not grow with its length). Returns the exit status.
int Play(const SimulateTrackerCommandOptions& o, SampleSource* source, const MacKey* key,
         const MacKey* service_key, const std::optional<Skeleton>& skeleton,
         std::vector<ClientState>* clients_ptr) {
  std::vector<ClientState>& clients = *clients_ptr;
  StopSignal stop;
  const int64_t session = o.session >= 0 ? o.session : WallClockUtime();
  // One client of the client library per id.
  std::map<std::string, std::unique_ptr<LiveClient>> live;
  std::shared_ptr<DaemonConnection> shared;  // Configured clients: one LCM instance.
  try {
    if (!o.join) {
      DaemonConnection::Options co;
      co.lcm_url = o.lcm_url;
      shared = std::make_shared<DaemonConnection>(std::move(co));
    }
    for (const ClientState& c : clients) {
      LiveClient::Options lo;
      lo.lcm_url = o.lcm_url;
      lo.channels.pose = o.channel;
      lo.client_id = c.id;
      if (key) lo.room_key = *key;
      if (service_key) lo.service_key = *service_key;
      lo.join = o.join;
      lo.session = session;
      lo.skeleton = skeleton;
      lo.ignore = o.ignore_rules;
      for (const std::string& rule : o.entity_rules) {
        lo.ignore_entities.push_back(ParseEntityRule(rule));
      }
      lo.shared_connection = shared;
      live[c.id] = std::make_unique<LiveClient>(std::move(lo));
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: simulate-tracker: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
  // Tracked objects: every usable line, by utime (unusable ones skipped and
  // counted, as pose lines are).
  std::vector<object_pose_t> objects;
  std::shared_ptr<DaemonConnection> object_connection = shared;
  int64_t object_lines_skipped = 0;
  try {
    for (const std::string& spec : o.objects) {
      const size_t eq = spec.find('=');
      if (eq == std::string::npos || eq == 0 || !IsValidClientId(spec.substr(0, eq))) {
        throw InputError(
            "--object '" + EscapeForDisplay(spec) +
            "': use ID=POSES.jsonl with an id of 1-64 characters from A-Z a-z 0-9 _ . -");
      }
      const std::string path = spec.substr(eq + 1);
      int64_t seq = 0;
      // The one object pose reader (the lines `sweptccd world` uses).
      object_lines_skipped += world::ReadObjectPoseFile(
          path, "object pose file (--object)", [&](const world::RigidSample& x) {
            object_pose_t m{};
            m.utime = x.utime + static_cast<int64_t>(o.bvh.utime_start);
            m.object_id = spec.substr(0, eq);
            m.session = session;
            m.seq = seq++;
            for (int c = 0; c < 3; ++c) m.position[c] = x.p[c];
            m.orientation[0] = x.q.w(), m.orientation[1] = x.q.x(), m.orientation[2] = x.q.y();
            m.orientation[3] = x.q.z();
            objects.push_back(m);
          });
    }
    std::stable_sort(
        objects.begin(), objects.end(),
        [](const object_pose_t& a, const object_pose_t& b) { return a.utime < b.utime; });
    if (!objects.empty() && !object_connection) {
      DaemonConnection::Options co;
      co.lcm_url = o.lcm_url;
      object_connection = std::make_shared<DaemonConnection>(std::move(co));
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: simulate-tracker: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
  size_t next_object = 0;
  int64_t objects_sent = 0;
  auto publish_objects_until = [&](int64_t utime, int64_t rebase) {
    for (; next_object < objects.size() && objects[next_object].utime <= utime; ++next_object) {
      object_pose_t m = objects[next_object];
      m.utime += rebase;
      const std::vector<uint8_t> bytes = EncodeSigned(m, key);
      if (object_connection->Publish(o.object_channel, bytes)) ++objects_sent;
    }
  };
  for (auto& [id, client] : live) {
    const JoinResult joined = client->Join();
    if (!joined.ok()) {
      // The reason comes from the network: escaped.
      std::fprintf(stderr, "error: simulate-tracker: join of '%s' refused (%d): %s\n", id.c_str(),
                   joined.reason, EscapeForDisplay(joined.message, 1024).c_str());
      return 1;
    }
    if (o.join) {
      std::printf("simulate-tracker: '%s' joined, session %lld\n", id.c_str(),
                  static_cast<long long>(joined.session));
    }
  }
  std::fflush(stdout);
  // A pose file with --rate: a fixed publication period; otherwise the utimes'.
  const bool fixed_rate = o.poses_path.empty() ? false : o.bvh.rate_hz > 0;
  RoundCounters counters(o.seed);
  int64_t sent = 0;
  bool publish_failed = false;
  auto publish = [&](const tracker_pose_t& m) {
    if (!live.at(m.client_id)->PublishPose(m)) publish_failed = true;
    ++sent;
  };

  const Clock::time_point t0 = Clock::now();
  const Clock::time_point end = o.duration_s > 0
                                    ? t0 + std::chrono::duration_cast<Clock::duration>(
                                               std::chrono::duration<double>(o.duration_s))
                                    : Clock::time_point::max();
  StreamShape shape;
  int64_t rebase_us = 0;
  int64_t loops_done = 0, rounds = 0;
  bool stopped = false;
  for (int64_t loop = 0; (o.loops == 0 || loop < o.loops) && !stopped; ++loop) {
    if (loop > 0) source->Rewind();
    int64_t k = 0;
    // A later pass plays at most the first pass's count (seq stays increasing).
    for (; (loop == 0 || k < shape.n) && !stopped; ++k) {
      std::optional<Pose> sample = source->Next();
      if (!sample) break;
      sample->utime += static_cast<int64_t>(o.bvh.utime_start);
      if (loop == 0) {
        if (k == 0) shape.first_utime = sample->utime;
        if (k == 0 && o.rebase_utime) rebase_us = WallClockUtime() - shape.first_utime;
        shape.last_utime = sample->utime;
        shape.n = k + 1;
      }
      const int64_t utime = sample->utime + loop * shape.loop_span_us;
      const double due_s = fixed_rate
                               ? static_cast<double>(loop * shape.n + k) / o.bvh.rate_hz / o.speed
                               : static_cast<double>(utime - shape.first_utime) * 1e-6 / o.speed;
      const double jitter_s =
          o.jitter_us > 0 ? counters.unit(counters.rng) * o.jitter_us * 1e-6 : 0.0;
      const Clock::time_point due = t0 + std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>(due_s + jitter_s));
      if (due > end || stop.WaitUntil(due)) {
        stopped = true;
        break;
      }
      ++rounds;
      if (loop == 0) publish_objects_until(utime, rebase_us);
      SendRound(o, *sample, utime + rebase_us, utime, shape.first_utime, session,
                o.seq_start + loop * shape.n + k, &clients, &counters, publish);
    }
    if (loop == 0) {
      if (shape.n == 0 && !stopped) {
        throw InputError(o.poses_path + ": no pose to send" +
                         (o.bvh.start_frame > 0
                              ? " from --start " + std::to_string(o.bvh.start_frame)
                              : std::string()));
      }
      FinishFirstPass(o, &shape);
    }
    if (!stopped) ++loops_done;
  }
  // A sample still held (stopped early, the last one, or every later sample
  // dropped): sent now, after nothing newer, so the daemon accepts it: not
  // counted as late.
  for (ClientState& c : clients) {
    if (c.held) {
      publish(*c.held);
      c.held.reset();
    }
  }
  if (!stopped && !objects.empty()) publish_objects_until(INT64_MAX - 1, rebase_us);
  if (!objects.empty()) {
    std::printf("simulate-tracker: %lld object poses sent, %lld object line(s) skipped\n",
                static_cast<long long>(objects_sent), static_cast<long long>(object_lines_skipped));
  }
  for (auto& [id, client] : live) client->Leave();
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf(
      "simulate-tracker: sent %lld, dropped %lld, late %lld (%zu clients x %lld samples, "
      "%lld loop(s), %.3f s), skipped %lld malformed line(s)\n",
      static_cast<long long>(sent), static_cast<long long>(counters.dropped),
      static_cast<long long>(counters.late), clients.size(), static_cast<long long>(rounds),
      static_cast<long long>(loops_done), elapsed_s, static_cast<long long>(source->skipped()));
  std::fflush(stdout);
  if (publish_failed) {
    std::fprintf(stderr, "error: simulate-tracker: LCM publish on %s failed\n", o.channel.c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int RunSimulateTrackerCommand(const SimulateTrackerCommandOptions& o) {
  std::unique_ptr<SampleSource> source;
  std::vector<ClientState> clients;
  std::optional<MacKey> key, service_key;
  std::optional<Skeleton> skeleton;
  try {
    CheckOptions(o);
    if (o.session < -1) throw InputError("simulate-tracker: --session must be >= 0");
    if (!o.key_path.empty()) key = LoadKeyFile(o.key_path);
    if (!o.service_key_path.empty()) service_key = LoadKeyFile(o.service_key_path);
    source = MakeSource(o, &skeleton);
    if (o.join && !skeleton) {
      throw InputError("simulate-tracker: --join needs --skeleton (or --bvh) to join with");
    }
    if (!o.join && (!o.entity_rules.empty() || !o.ignore_rules.empty())) {
      throw InputError(
          "simulate-tracker: --join-ignore and --join-ignore-entity are sent with "
          "a join: give --join");
    }
    for (const std::string& rule : o.entity_rules) ParseEntityRule(rule);
    clients = MakeClients(o);
    SetClientRates(o, &clients);
    source->Rewind();  // A pose file that cannot be opened is refused before LCM starts.
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
  if (!key) {
    std::fprintf(stderr,
                 "simulate-tracker: no --key: poses are sent UNSIGNED (a daemon in signed "
                 "mode refuses them)\n");
  }
  try {
    return Play(o, source.get(), key ? &*key : nullptr, service_key ? &*service_key : nullptr,
                skeleton, &clients);
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}

}  // namespace sweptccd
