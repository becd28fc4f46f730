#include "core/gpu/device_descent.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <system_error>

#include "core/avatar/motion.h"
#include "core/errors.h"
#include "core/gpu/cull_dispatch.h"
#include "core/gpu/descent_dispatch.h"
#include "core/gpu/gpu_environment_buffers.h"
#include "core/query/swept_bounds.h"
#include "core/worker_pool.h"

namespace sweptccd::gpu {

namespace {

using Clock = std::chrono::steady_clock;

double MicrosSince(Clock::time_point start) {
  return std::chrono::duration<double, std::micro>(Clock::now() - start).count();
}

// Calls work(i) once for every i in [0, n): on the pool's workers, in
// contiguous chunks (a few per worker, at least `min_chunk` items each, so
// that waking the workers costs less than the chunk), when there is a pool
// and at least two such chunks; else here. Each i writes its own outputs
// only, so the results are the same either way.
void ForEach(WorkerPool* pool, size_t n, size_t min_chunk,
             const std::function<void(size_t)>& work) {
  const size_t chunks =
      pool == nullptr ? 0 : std::min(n / min_chunk, static_cast<size_t>(pool->size()) * 8);
  if (chunks < 2) {
    for (size_t i = 0; i < n; ++i) work(i);
    return;
  }
  pool->Run(chunks, [&](size_t c, int) {
    const size_t end = n * (c + 1) / chunks;
    for (size_t i = n * c / chunks; i < end; ++i) work(i);
  });
}

// The fewest items a worker takes at once: the whole preparation of a pair
// of 20 links took 25-30 us on one thread of the development machine
// (docs/GPU.md, "Where the device descent's time goes"), so a chunk of 8
// pairs or 64 tracks is some 100 us, well above waking the workers.
constexpr size_t kPairsPerChunk = 8, kTracksPerChunk = 64;

using internal::DescentItem;
using internal::DescentPoint;
using internal::DescentTrack;

float RoundUp(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// What a float holds safely (the shader never sees more; docs/GPU.md).
bool Usable(double x) { return std::fabs(x) <= 1e30; }  // NaN: false.

// The grid point of `link` at s: the segment as SegmentAt computes it (the
// bits the CPU's descent computes for the same s), rounded to nearest, and
// the larger endpoint displacement of that rounding, rounded up. False when
// a float cannot hold it.
bool GridPoint(const PairMotion& motion, LinkIndex link, double s, DescentPoint* out) {
  Eigen::Vector3d a, b;
  motion.SegmentAt(link, s, &a, &b);
  for (int k = 0; k < 3; ++k) {
    if (!Usable(a[k]) || !Usable(b[k])) return false;
    out->a_d[k] = static_cast<float>(a[k]);
    out->b[k] = static_cast<float>(b[k]);
  }
  const Eigen::Vector3d af(out->a_d[0], out->a_d[1], out->a_d[2]);
  const Eigen::Vector3d bf(out->b[0], out->b[1], out->b[2]);
  const double moved = std::max((af - a).norm(), (bf - b).norm()) * (1 + 1e-12);
  if (!Usable(moved)) return false;
  out->a_d[3] = RoundUp(moved);
  out->b[3] = 0;
  return true;
}

// The track's growth constants (rad), rounded up, such that for every depth
// d below `levels` the device's radius before its own rounding,
// rad[0] + rad[1] 2^-(d + 1) + rad[2], is at least the CPU's radius of
// every interval at that depth with its first-order growth (SweptBounds:
// (link radius + growth) + tolerance, growth = min(first order, second
// order) <= SweepRadius, which depends on the width alone). Checked here
// for every depth, with a relative margin of 2^-40 that covers this
// check's own double roundings. False when not (the track is not sent).
bool Radii(const PairMotion& motion, double link_radius, double tolerance, LinkIndex link,
           int levels, float rad[4]) {
  const double whole = motion.SweepRadius(link, 0.0, 1.0);
  const double slack = motion.rounding_slack();
  rad[0] = RoundUp((link_radius + tolerance) * (1 + 1e-12));
  rad[1] = RoundUp(2 * whole * (1 + 1e-12));
  rad[2] = RoundUp(slack * (1 + 1e-12));
  rad[3] = 0;
  for (int k = 0; k < 3; ++k) {
    if (!Usable(rad[k]) || !(rad[k] >= 0)) return false;
  }
  // The shader's box growth needs r >= 1e-20 (device_descent.cc's shader).
  if (!(rad[0] >= 1e-20f)) return false;
  for (int d = 0; d < levels; ++d) {
    const double width = std::ldexp(1.0, -d);
    const double cpu = (link_radius + motion.SweepRadius(link, 0.0, width)) + tolerance;
    const double device = static_cast<double>(rad[0]) +
                          static_cast<double>(rad[1]) * std::ldexp(1.0, -(d + 1)) +
                          static_cast<double>(rad[2]);
    if (!(device >= cpu * (1 + std::ldexp(1.0, -40)))) return false;
  }
  return true;
}

}  // namespace

struct DeviceDescent::State {
  struct EngineEntry {
    const CcdEngine* engine;
    uint32_t masks_offset;
    size_t masks_size;
  };
  std::vector<EngineEntry> engines;  // A removed one: engine null, masks freed.
  std::unique_ptr<internal::DescentDispatch> dispatch;
  DescentStats stats;
  bool failed = false;
};

DeviceDescent::DeviceDescent(std::shared_ptr<const GpuEnvironment> environment,
                             const Environment& source, DescentOptions options)
    : env_(std::move(environment)),
      content_id_(source.content_id()),
      options_(options),
      state_(std::make_unique<State>()) {
  options_.levels = std::clamp(options_.levels, 1, PairClears::kMaxLevels);
  options_.pair_budget = std::max(0, options_.pair_budget);
  options_.queue_capacity = std::max(2, options_.queue_capacity);
  options_.host_threads = std::clamp(options_.host_threads, 1, 1024);
  options_.max_steps =
      std::clamp(options_.max_steps, 1, static_cast<int>(internal::kMaxSearchSteps));
  if (options_.host_threads > 1) {
    try {
      pool_ = std::make_unique<WorkerPool>(options_.host_threads);
    } catch (const std::system_error& e) {  // No threads to be had (a task limit, say).
      spdlog::warn(
          "GPU device descent: {} preparation threads could not start ({}); it prepares "
          "on the calling thread",
          options_.host_threads - 1, e.what());
      options_.host_threads = 1;
    }
  }
  const GpuEnvironment::Buffers& b = env_->buffers();
  State& s = *state_;
  env_->context().Run([&] {
    s.dispatch = std::make_unique<internal::DescentDispatch>(
        b.nodes, b.tris, b.objects, static_cast<GLuint>(env_->num_objects()));
  });
}

DeviceDescent::~DeviceDescent() {
  State* s = state_.get();
  internal::CullDispatch* dispatch = env_->buffers().dispatch.get();
  try {
    env_->context().Run([s, dispatch] {
      for (const State::EngineEntry& e : s->engines) {
        if (e.engine != nullptr) dispatch->RemoveMasks(e.masks_offset, e.masks_size);
      }
      s->dispatch.reset();
    });
  } catch (const GpuError&) {
    (void)s->dispatch.release();  // A lost context took its objects with it.
  }
}

int DeviceDescent::AddEngine(const CcdEngine& engine) {
  if (engine.environment().content_id() != content_id_) {
    throw GpuError("the device descent was made for another environment");
  }
  std::lock_guard<std::mutex> lock(mutex_);
  State& s = *state_;
  FreeRetiredLocked();
  const int num_links = engine.skeleton().num_links();
  const int mask_words = std::max(1, (env_->num_objects() + 31) / 32);
  std::vector<uint32_t> masks(static_cast<size_t>(std::max(1, num_links)) * mask_words, 0u);
  for (LinkIndex l(0); l < num_links; ++l) {
    for (ObjectIndex o(0); o < env_->num_objects(); ++o) {
      if (engine.filter().Ignores(l, o)) masks[l * mask_words + o / 32] |= 1u << (o % 32);
    }
  }
  internal::CullDispatch& dispatch = *env_->buffers().dispatch;
  uint32_t offset = 0;
  env_->context().Run([&] { offset = dispatch.AddMasks(masks); });
  // A removed engine's slot is taken again (a daemon's clients come and go).
  for (size_t i = 0; i < s.engines.size(); ++i) {
    if (s.engines[i].engine == nullptr) {
      s.engines[i] = {&engine, offset, masks.size()};
      return static_cast<int>(i);
    }
  }
  s.engines.push_back({&engine, offset, masks.size()});
  return static_cast<int>(s.engines.size()) - 1;
}

void DeviceDescent::RemoveEngine(int index) {
  std::lock_guard<std::mutex> lock(retired_mutex_);
  retired_.push_back(index);
}

void DeviceDescent::FreeRetiredLocked() {
  std::vector<int> retired;
  {
    std::lock_guard<std::mutex> lock(retired_mutex_);
    retired.swap(retired_);
  }
  if (retired.empty()) return;
  State& s = *state_;
  internal::CullDispatch& dispatch = *env_->buffers().dispatch;
  for (int index : retired) {
    SWEPTCCD_CHECK(index >= 0 && index < static_cast<int>(s.engines.size()) &&
                   s.engines[index].engine != nullptr);
    s.engines[index].engine = nullptr;
  }
  try {
    env_->context().Run([&] {
      for (int index : retired) {
        dispatch.RemoveMasks(s.engines[index].masks_offset, s.engines[index].masks_size);
      }
    });
  } catch (const GpuError&) {
    // A lost context took its buffers with it; the slots are free all the same.
  }
}

std::string DescentTimes(const DescentStats& stats) {
  char line[160];
  std::snprintf(line, sizeof(line),
                "in Run: host preparation %.1f ms, device %.1f ms, rest %.1f ms",
                stats.host_us / 1000, stats.device_us / 1000, stats.other_us / 1000);
  return line;
}

DescentStats DeviceDescent::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_->stats;
}

bool DeviceDescent::Run(const std::vector<Pair>& pairs, const QueryOptions& options,
                        std::vector<PairClears>* clears) {
  std::lock_guard<std::mutex> lock(mutex_);
  State& s = *state_;
  // Where the time goes (DescentStats::host_us, device_us, other_us),
  // counted at every return.
  struct Timing {
    DescentStats* stats;
    Clock::time_point start = Clock::now();
    double host_us = 0, device_us = 0;
    ~Timing() {
      const double total = MicrosSince(start);
      stats->host_us += host_us;
      stats->device_us += device_us;
      stats->other_us += std::max(0.0, total - host_us - device_us);
    }
  } timing{&s.stats};
  FreeRetiredLocked();
  const int levels = options_.levels;
  clears->resize(pairs.size());
  std::vector<size_t> first_link(pairs.size() + 1, 0);  // Per pair: its first link's slot.
  for (size_t i = 0; i < pairs.size(); ++i) {
    SWEPTCCD_CHECK(pairs[i].engine >= 0 && pairs[i].engine < static_cast<int>(s.engines.size()));
    const int num_links = s.engines[pairs[i].engine].engine->skeleton().num_links();
    (*clears)[i].Reset(num_links, levels);
    first_link[i + 1] = first_link[i] + static_cast<size_t>(num_links);
  }
  if (s.failed || pairs.empty()) return !s.failed;
  for (const Pair& pair : pairs) SWEPTCCD_CHECK(pair.pose1->utime > pair.pose0->utime);
  ++s.stats.batches;
  s.stats.pairs += static_cast<int64_t>(pairs.size());

  // The host's preparation, pair by pair (independent): the pairs' motions,
  // as their queries will build them, and each link's growth constants and
  // grid point at the middle (false: a float cannot hold them).
  struct LinkPrep {
    float rad[4];
    DescentPoint centre;
    bool ok;
  };
  std::vector<std::unique_ptr<PairMotion>> motions(pairs.size());
  std::vector<LinkPrep> prep(first_link.back());
  Clock::time_point phase = Clock::now();
  ForEach(pool_.get(), pairs.size(), kPairsPerChunk, [&](size_t i) {
    const State::EngineEntry& e = s.engines[pairs[i].engine];
    const Skeleton& skeleton = e.engine->skeleton();
    motions[i] = std::make_unique<PairMotion>(skeleton, *pairs[i].pose0, *pairs[i].pose1,
                                              pairs[i].motion.value_or(options.motion));
    const PairMotion& motion = *motions[i];
    const double tolerance =
        sweptccd::internal::SweptBounds::Tolerance(e.engine->environment(), motion);
    for (LinkIndex l(0); l < skeleton.num_links(); ++l) {
      LinkPrep& p = prep[first_link[i] + static_cast<size_t>(l.value())];
      p = LinkPrep{};
      p.ok = Radii(motion, skeleton.link(l).radius, tolerance, l, levels, p.rad) &&
             GridPoint(motion, l, 0.5, &p.centre);
    }
  });
  timing.host_us += MicrosSince(phase);

  // The tracks, in the pairs' order and each pair's links' order.
  struct TrackOf {
    uint32_t pair;
    LinkIndex link;
  };
  std::vector<TrackOf> owners;
  std::vector<DescentTrack> tracks;
  const size_t per_track = (size_t{1} << levels) + 1;
  const uint32_t mid = 1u << (levels - 1);
  std::vector<DescentItem> items;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const State::EngineEntry& e = s.engines[pairs[i].engine];
    for (size_t slot = first_link[i]; slot < first_link[i + 1]; ++slot) {
      const LinkPrep& p = prep[slot];
      if (!p.ok) {
        ++s.stats.refused;
        continue;
      }
      const auto index = static_cast<uint32_t>(tracks.size());
      const LinkIndex l(static_cast<int>(slot - first_link[i]));
      DescentTrack t{};
      std::copy(p.rad, p.rad + 4, t.rad);
      t.meta[0] = static_cast<uint32_t>(l.value());
      t.meta[1] = e.masks_offset;
      t.meta[2] = static_cast<uint32_t>(i);
      t.meta[3] = static_cast<uint32_t>(index * per_track);
      tracks.push_back(t);
      owners.push_back({static_cast<uint32_t>(i), l});
      items.push_back({index, 0u});
    }
  }
  // The grid: zeros but each track's middle point (the other points of the
  // tracks left open are written below), track by track on the workers: the
  // first touch of 33 points of 32 bytes per track (86 MB for 4,096 pairs of
  // 20 links) is spread over them, not zeroed on this thread.
  std::unique_ptr<DescentPoint[]> grid(new DescentPoint[tracks.size() * per_track]);
  phase = Clock::now();
  ForEach(pool_.get(), tracks.size(), kTracksPerChunk, [&](size_t t) {
    DescentPoint* g = grid.get() + t * per_track;
    std::fill(g, g + per_track, DescentPoint{});
    g[mid] = prep[first_link[owners[t].pair] + static_cast<size_t>(owners[t].link.value())].centre;
  });
  timing.host_us += MicrosSince(phase);
  const size_t grid_size = tracks.size() * per_track;
  s.stats.tracks += static_cast<int64_t>(tracks.size());
  std::vector<uint32_t> cleared(tracks.size(), 0u), pushed(pairs.size(), 0u),
      flags(pairs.size(), 0u);
  internal::DescentLevels run;
  run.grid_levels = levels;
  run.pair_budget = static_cast<uint32_t>(options_.pair_budget);
  run.capacity = static_cast<uint32_t>(options_.queue_capacity);
  run.max_steps = static_cast<uint32_t>(options_.max_steps);
  internal::CullDispatch& cull = *env_->buffers().dispatch;
  try {
    // The whole pair first (the link culling step), for every link.
    run.stop_depth = 1;
    int dispatches = 0;
    int64_t tested = 0;
    phase = Clock::now();
    env_->context().Run([&] {
      dispatches += s.dispatch->Run(tracks, grid.get(), grid_size, items, run, cull.masks_buffer(),
                                    cull.mask_words(), &pushed, &flags, &cleared, &tested);
    });
    timing.device_us += MicrosSince(phase);
    // The open links' trees: their grids (only for them), then the levels
    // below, appended on the device.
    items.clear();
    if (levels > 1) {
      // Track by track (independent): the grid points but the middle one
      // (grid_ok[t] = 0: a float cannot hold one; the track is not sent).
      std::vector<uint8_t> grid_ok(tracks.size(), 0);
      phase = Clock::now();
      ForEach(pool_.get(), tracks.size(), kTracksPerChunk, [&](size_t t) {
        if (cleared[t] & 1u) return;
        const PairMotion& motion = *motions[owners[t].pair];
        bool ok = true;
        for (uint32_t j = 0; j < per_track && ok; ++j) {
          if (j == mid) continue;
          ok = GridPoint(motion, owners[t].link, std::ldexp(static_cast<double>(j), -levels),
                         &grid[t * per_track + j]);
        }
        grid_ok[t] = ok ? 1 : 0;
      });
      timing.host_us += MicrosSince(phase);
      std::vector<uint32_t> open_links(pairs.size(), 0u);
      for (size_t t = 0; t < tracks.size(); ++t) {
        if (cleared[t] & 1u) continue;
        if (grid_ok[t] == 0) {
          ++s.stats.refused;
          continue;
        }
        ++open_links[owners[t].pair];
      }
      for (size_t t = 0; t < tracks.size(); ++t) {
        if (grid_ok[t] == 0) continue;
        const uint32_t p = owners[t].pair;
        if (2u * open_links[p] > run.pair_budget) {
          flags[p] |= internal::kOverPairBudget;  // Its halves are left to the CPU.
          continue;
        }
        items.push_back({static_cast<uint32_t>(t), 1u << 24});
        items.push_back({static_cast<uint32_t>(t), (1u << 24) | 1u});
        pushed[p] += 2;
      }
      run.stop_depth = levels;
      if (!items.empty()) {
        phase = Clock::now();
        env_->context().Run([&] {
          dispatches +=
              s.dispatch->Run(tracks, grid.get(), grid_size, items, run, cull.masks_buffer(),
                              cull.mask_words(), &pushed, &flags, &cleared, &tested);
        });
        timing.device_us += MicrosSince(phase);
      }
    }
    s.stats.dispatches += dispatches;
    s.stats.items += tested;
  } catch (const GpuError& e) {
    timing.device_us += MicrosSince(phase);
    s.failed = true;
    spdlog::error("GPU device descent failed, queries continue on the CPU: {}", e.what());
    for (size_t i = 0; i < pairs.size(); ++i) {
      (*clears)[i].Reset(s.engines[pairs[i].engine].engine->skeleton().num_links(), levels);
    }
    return false;
  }
  for (size_t t = 0; t < tracks.size(); ++t) {
    PairClears& c = (*clears)[owners[t].pair];
    c.SetWord(owners[t].link, cleared[t]);
  }
  for (size_t i = 0; i < pairs.size(); ++i) {
    s.stats.cleared += (*clears)[i].count();
    if (flags[i] != 0) ++s.stats.over_budget;
  }
  return true;
}

}  // namespace sweptccd::gpu
