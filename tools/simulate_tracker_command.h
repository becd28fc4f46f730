#pragma once
// `sweptccd simulate-tracker`: plays a pose stream (a SPEC pose file, or a BVH
// clip imported in-process as `sweptccd import-bvh` does) as tracker_pose_t
// messages over LCM, for one or more clients, in real time or faster, with
// optional timing jitter, dropped samples and late (out-of-order) samples.
//
// What is sent, per client c (index i) and sample k of loop L:
//   client_id  the client's id;
//   seq        seq_start + L * samples + k (strictly increasing);
//   utime      the sample's utime (+ utime_start) + L * loop_span, where
//              loop_span = last - first utime + one sample interval, so loops
//              keep utime increasing; with rebase_utime the first sample's
//              utime is replaced by the wall clock at start (same spacing);
//   positions  the sample's positions + offset + i * spacing.
// A client with its own rate and phase (--client-rate, --client-phase-us)
// sends only the samples its ticks select (below), each with its own seq.
// Sample k of every client is due at (utime_k - utime_0) / speed after the
// start (or k / rate / speed with --rate for a pose file), plus a uniform
// random delay in [0, jitter_us]. A dropped sample is never sent; a late
// sample is held back and sent right after the client's next sent sample (so
// its seq and utime are older than the last one the daemon accepted: the
// daemon rejects it as non_increasing_seq). The random choices come from one
// generator seeded with `seed`: the same flags give the same messages.
//
// A pose file is streamed: each sample is read (core PoseLineReader: query's
// blank lines, utime parsing and line cap) just before it is due, so memory
// does not grow with the file and a FIFO plays as it is written; the first
// pass fixes `samples` and loop_span, later passes re-open the file. A line
// that is no pose is skipped with a warning and counted (SPEC 2: an invalid
// pose is not fatal); poses are sent as written, for the daemon to validate.
//
// Every client is a LiveClient of the client library (client/): a configured
// client signs with --key and sends --session; with --join each joins first
// (docs/SERVICE.md, "Live clients") and leaves at the end.

#include <cstdint>
#include <string>
#include <vector>

#include "msgs/channels.h"
#include "tools/import_bvh_command.h"

namespace CLI {
class App;
}

namespace sweptccd {

struct SimulateTrackerCommandOptions {
  std::string lcm_url;  // Empty: LCM's default (LCM_DEFAULT_URL or udpm).
  std::string channel = kPoseChannel;
  std::string object_channel = kObjectPoseChannel;  // --object's object_pose_t.
  std::string key_path;  // Signs every pose; empty: unsigned.
  int64_t session = -1;  // tracker_pose_t.session; -1: the wall clock (us) at start.
  std::string poses_path;               // A SPEC pose stream (JSON Lines), or
  ImportBvhCommandOptions bvh;          // bvh.bvh_path: a BVH clip (import-bvh's options).
  std::string skeleton_path;            // Optional: checks the link count.
  std::vector<std::string> client_ids;  // --client, repeated; or
  int num_clients = -1;                 // --clients N: prefix0 .. prefix(N-1); -1: not given.
  std::string client_prefix = "client";
  std::vector<double> spacing{2.0, 0.0, 0.0};  // Metres per client index.
  double speed = 1.0;                          // Playback speed factor, > 0.
  int loops = 1;                               // Times the stream is played; 0: until stopped.
  double jitter_us = 0;                        // Max random delay of a publication, microseconds.
  double drop_p = 0;                           // Probability a sample is not sent.
  double late_p = 0;                           // Probability a sample is sent after the next one.
  uint64_t seed = 1;
  double duration_s = 0;  // Wall-clock limit, seconds; 0: none.
  int64_t seq_start = 0;
  bool rebase_utime = false;
  /// Live clients: each client joins (SWEPTCCD_JOIN) with the skeleton
  /// (--skeleton, or the BVH clip's), sends with the session and key its
  /// reply gives, and leaves at the end; key_path is then the room key.
  bool join = false;
  std::string service_key_path;  // Verifies join replies; default: key_path.
  std::vector<std::string> ignore_rules;  // --join: LINK:OBJECT filter rules.
  /// --join: the shared world's filters, LINK:ENTITY or LINK:ENTITY:OTHER_LINK.
  std::vector<std::string> entity_rules;
  /// --object ID=POSES.jsonl, repeated: tracked objects of the shared world
  /// (SPEC 8 object pose lines), published as object_pose_t on
  /// SWEPTCCD_OBJECT_POSE interleaved by utime with the avatars' samples
  /// (first pass only; --utime-start and --rebase-utime apply), signed with
  /// --key, with the avatars' session.
  std::vector<std::string> objects;
  /// --client-rate ID=HZ and --client-phase-us ID=US, repeated: client ID
  /// plays at its own rate and phase. Its ticks are at first_utime + US +
  /// m * 1e6 / HZ (m = 0, 1, ...; over the looped utimes); at each tick it
  /// sends the first sample of the stream at or after the tick that it has
  /// not sent yet, as is (utime, pose, due time): what it sends is a subset
  /// of the stream, at most one sample a tick (so at most the stream's own
  /// rate). A phase needs a rate, 0 <= US < 1e6 / HZ; HZ in (0, 10000].
  std::vector<std::string> client_rates, client_phases;
};

void AddSimulateTrackerOptions(CLI::App* app, SimulateTrackerCommandOptions* options);

/// Runs the command. Prints one summary line on standard output at the end
/// ("simulate-tracker: sent N, dropped D, late L ..."). Returns 0 when done
/// (or stopped by SIGINT/SIGTERM), 2 with a one-line message on standard
/// error for bad input (a file, a line, a flag), 1 when LCM fails.
int RunSimulateTrackerCommand(const SimulateTrackerCommandOptions& options);

}  // namespace sweptccd
