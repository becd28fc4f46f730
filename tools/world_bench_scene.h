#pragma once
// The scene of `sweptccd world-bench` (tools/world_bench_command.h), shared
// by its scenarios: the breakfast room and where the group stands, the clips
// and rates of the avatars, and the files a generated world is written as.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "mocap/mocap_import.h"

namespace sweptccd::world_bench {

// The room and where the group stands: the breakfast room (Y-up, floor at
// y = -1.42), the grid centred on the free strip between the table's chairs
// (the centre `sweptccd bench` walks around).
inline constexpr char kRoom[] = "bitterli_breakfast_room.ply";
inline constexpr double kFloor = -1.42;
inline const Eigen::Vector2d kCentre(-0.67, -1.9);
inline constexpr int64_t kUtime0 = 1'000'000;

// Clips that stay roughly in place (a grid of walkers would leave it), each
// avatar from its own start second; rates cycle 90 / 72 / 60 Hz.
struct ClipChoice {
  const char* file;
  double start_s;
};
inline constexpr ClipChoice kClips[] = {
    {"boxing_toes.bvh", 0},
    {"cmu_13_10_jump_grab_reach_tiptoe.bvh", 0},
    {"cmu_01_03_playground_climb_hang_swing.bvh", 0},
    {"cmu_02_04_jump_balance.bvh", 0},
    {"boxing_toes.bvh", 5},
    {"cmu_13_10_jump_grab_reach_tiptoe.bvh", 6},
    {"cmu_05_06_dance_cartwheel_pirouettes_jete.bvh", 0},
    {"cmu_03_01_walk_uneven_terrain.bvh", 0},
    {"boxing_toes.bvh", 10},
    {"cmu_13_10_jump_grab_reach_tiptoe.bvh", 12},
    {"cmu_01_03_playground_climb_hang_swing.bvh", 10},
    {"cmu_01_01_playground_forward_jumps.bvh", 0},
    {"boxing_toes.bvh", 15},
    {"cmu_01_03_playground_climb_hang_swing.bvh", 20},
    {"boxing_toes.bvh", 20},
    {"cmu_01_01_playground_forward_jumps.bvh", 10},
};
inline constexpr double kRates[] = {90, 72, 60};
inline constexpr double kThrownRate = 120;

/// Writes `text` to `path`; throws InputError when it cannot.
void WriteText(const std::filesystem::path& path, const std::string& text);

/// A closed box mesh (12 triangles, OBJ text) centred at the object frame's
/// origin, half extents `half` along its axes.
std::string BoxObj(const Eigen::Vector3d& half);

/// One tracked-object pose line (SPEC 8), with its newline.
std::string ObjectPoseLine(int64_t utime, const Eigen::Vector3d& p, const Eigen::Quaterniond& q);

/// `seconds` of the clip from `start_s` (moved earlier when the clip ends
/// first), resampled at `rate_hz` by the clip's articulated motion between
/// its frames (so bone lengths stay those of the clip); utimes from 0.
std::vector<Pose> Resample(const MocapClip& clip, double start_s, double rate_hz, double seconds);

/// Avatar k's clip (kClips[k mod 16], Y-up), resampled at kRates[k mod 3]
/// for `seconds`, stood in grid cell k of `cols` x `rows` cells `spacing`
/// metres apart on the room's floor; utimes from kUtime0 + 1000 k.
MocapClip GridAvatarClip(const std::string& data, int k, int cols, int rows, double spacing,
                         double seconds);

}  // namespace sweptccd::world_bench
