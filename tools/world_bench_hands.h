#pragma once
// `sweptccd world-bench --scenario hands` (issue 31): hands reaching for,
// grasping and carrying tracked objects, full-body avatars beside 16-link
// ones in the same run. Every avatar of the world-bench grid (its clip, rate
// and cell) reaches with one hand (the right for even k, the left for odd)
// for its own object, a small box resting where that hand will be at the
// grasp time, grasps it (the fingers curl round it), carries it (the box
// follows the hand) and releases it (the box stays where it was let go).
// Two worlds, the same clips, objects and times:
//   world16.json: the 16-link CMU avatars (one capsule a hand);
//   world81.json: the 81-link XR_META_body_tracking_full_body avatars
//     (--hands full), joint frames from the same 16 links with
//     PROCEDURALLY ANIMATED fingers (mocap/full_body_frames.h): open while
//     reaching, closed from the grasp to the release, the other hand on the
//     3 s grasp cycle of sweptccd_full_body_bench.
// No ignore rules: the fingers' and hand's contacts with the box are what
// is answered (SPEC 8 keeps rules per world file, not per sample). The grasp
// and release times and each box's size and grip are drawn from --seed.

#include <cstdint>
#include <string>

namespace sweptccd {

struct WorldBenchOptions;

/// Writes both worlds into options.out_dir (world16.json, world81.json and
/// the files they name) and, unless options.generate_only, answers every
/// record of both, alternating the two worlds record by record, and prints
/// the per-record table and the tallies. Throws InputError for unreadable
/// data.
void RunHandsScenario(const WorldBenchOptions& options, const std::string& data_dir);

}  // namespace sweptccd
