#pragma once
// Private to core/gpu: the device descent's dispatches (docs/GPU.md, "The
// free part of the descent on the device"). Level by level, breadth first:
// each invocation takes one work item (a track, the pair-link whose tree it
// belongs to, and a node of that tree), computes the node's swept capsule on
// the device from the track's segments and growth constants, grown by the
// error bound of that computation, runs the swept-volume search of
// SearchGlsl (cull_dispatch.h), and either marks the node cleared in the
// track's word or appends its two halves to the next level's queue (atomic
// counters: the queue's, and the pair's node budget). The host reads the
// queue's count between levels. Every method runs on the context's owner
// thread (inside GlContext::Run); nothing here locks.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/gpu/gl_api.h"

namespace sweptccd::gpu::internal {

/// A pair-link's tree as the shader reads it (std430): meta = (link, mask
/// table offset in words, pair, first grid point), rad = (radius and
/// tolerance, twice the first-order speed, rounding slack, 0), all rounded
/// up (DeviceDescent).
struct DescentTrack {
  uint32_t meta[4];
  float rad[4];
};
static_assert(sizeof(DescentTrack) == 32, "std430 layout of Track");

/// One grid point of a track: its segment at s = j 2^-levels, rounded to
/// nearest, a_d[3] = the larger endpoint displacement of that rounding,
/// rounded up.
struct DescentPoint {
  float a_d[4];
  float b[4];
};
static_assert(sizeof(DescentPoint) == 32, "std430 layout of a grid point");

/// A work item: the track and the node, (depth << 24) | k.
struct DescentItem {
  uint32_t track;
  uint32_t node;
};

/// Over-budget flags per pair (the pair's node budget, the queue's capacity).
constexpr uint32_t kOverPairBudget = 1u, kOverCapacity = 2u;

struct DescentLevels {
  int grid_levels = 0;       // Grid points per track: 2^grid_levels + 1.
  int stop_depth = 0;        // Nodes at depths below this are tested, deeper never.
  uint32_t pair_budget = 0;  // Items a pair may append (counted from `pushed`).
  uint32_t capacity = 0;     // Items one level's queue holds (even).
  uint32_t max_steps = 0;    // The search's step cap (1 to kMaxSearchSteps; clamped).
};

class DescentDispatch {
 public:
  /// Compiles the program. Throws GpuError.
  DescentDispatch(GLuint nodes, GLuint tris, GLuint objects, GLuint num_objects);
  ~DescentDispatch();
  DescentDispatch(const DescentDispatch&) = delete;
  DescentDispatch& operator=(const DescentDispatch&) = delete;

  /// Runs the levels from `items` (any depths below stop_depth) until the
  /// queue is empty or stop_depth is reached; `grid`: grid_size points
  /// (2^grid_levels + 1 per track, from the track's meta[3]). `pushed[p]` (in: items pair p
  /// already holds; out: after the run) and `flags[p]` (out, ORed) per pair;
  /// `cleared[t]` (out, ORed) per track: bit 2^depth - 1 + k. `masks` and
  /// `mask_words`: the filters' mask buffer (CullDispatch). Returns the
  /// dispatches made; adds the items tested to *tested. Throws GpuError.
  int Run(const std::vector<DescentTrack>& tracks, const DescentPoint* grid, size_t grid_size,
          const std::vector<DescentItem>& items, const DescentLevels& levels, GLuint masks,
          uint32_t mask_words, std::vector<uint32_t>* pushed, std::vector<uint32_t>* flags,
          std::vector<uint32_t>* cleared, int64_t* tested);

 private:
  GLuint nodes_, tris_, objects_, num_objects_;
  GLuint program_ = 0;
  // Tracks, grid, two queues, counters, cleared words.
  GLuint buffers_[6] = {0, 0, 0, 0, 0, 0};
  GLint loc_[9] = {-1, -1, -1, -1, -1, -1, -1, -1, -1};
};

}  // namespace sweptccd::gpu::internal
