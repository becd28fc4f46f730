#pragma once
// The GPU backend's swept-volume test: capsules against the environment's
// triangles in a compute shader, with outward-rounded single-precision
// tolerances, so that it only ever clears what is provably separated (see
// docs/GPU.md). The environment is uploaded once and stays resident.

#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/gpu/gl_context.h"
#include "core/gpu/transfer.h"
#include "core/query/capsule_culler.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"

namespace sweptccd::gpu {

/// Dispatches of one resident environment (all cullers on it, all threads).
struct DispatchStats {
  int64_t dispatches = 0;     // Compute dispatches (round trips to the GPU).
  int64_t requests = 0;       // Cull calls answered (the queries' round trips).
  int64_t capsules = 0;       // Capsules tested.
  int64_t largest = 0;        // Most capsules in one dispatch.
  int64_t most_requests = 0;  // Most requests in one dispatch.
};

/// An environment's BVH nodes and triangles held in GPU buffers. Immutable
/// after construction; shared by every culler (client) that tests against it.
class GpuEnvironment {
 public:
  /// Uploads every object's hierarchy and triangles and makes the
  /// swept-volume test's program and buffers; `transfer` says how capsules
  /// and answers cross (kBest: persistent mapped buffers with a fence where
  /// the context has them, else read-back; see core/gpu/cull_dispatch.h).
  /// Throws GpuError.
  GpuEnvironment(std::shared_ptr<GlContext> context, const Environment& environment,
                 Transfer transfer = Transfer::kBest);
  /// Frees the buffers on the context's owner thread.
  ~GpuEnvironment();
  GpuEnvironment(const GpuEnvironment&) = delete;
  GpuEnvironment& operator=(const GpuEnvironment&) = delete;

  GlContext& context() const { return *context_; }
  int num_objects() const { return num_objects_; }
  size_t uploaded_bytes() const { return uploaded_bytes_; }
  /// How capsules and answers cross: kReadBack or kPersistent.
  Transfer transfer() const { return transfer_; }
  /// The dispatches so far: every culler on this environment, every thread
  /// (their requests are coalesced, core/gpu/cull_combiner.h).
  DispatchStats dispatch_stats() const;
  /// The thread that dispatches first waits until `requests` requests are
  /// queued or `window` passed (default 1: never waits). Thread-safe.
  void SetGather(int requests, std::chrono::microseconds window) const;

  struct Buffers;  // GL names; private to core/gpu.
  const Buffers& buffers() const { return *buffers_; }

 private:
  std::shared_ptr<GlContext> context_;
  std::unique_ptr<Buffers> buffers_;
  int num_objects_ = 0;
  size_t uploaded_bytes_ = 0;
  Transfer transfer_ = Transfer::kReadBack;
};

/// CapsuleCuller on the GPU for one skeleton's links and one collision filter.
/// Thread-safe: work is handed to the context's owner thread. When the
/// context fails, the cause is logged once and Cull returns false from then
/// on (queries continue on the CPU path).
class GpuCuller : public CapsuleCuller {
 public:
  GpuCuller(std::shared_ptr<const GpuEnvironment> environment, const CollisionFilter& filter,
            int num_links);
  ~GpuCuller() override;

  bool Cull(const std::vector<LinkCapsule>& capsules,
            std::vector<uint8_t>* may_touch) const override;

  /// Requests answered (Cull calls that reached the GPU; several threads'
  /// requests may share one dispatch: GpuEnvironment::dispatch_stats) and
  /// capsules tested so far (all threads).
  int64_t round_trips() const;
  int64_t capsules_tested() const;

 private:
  struct State;
  std::shared_ptr<const GpuEnvironment> env_;
  std::unique_ptr<State> state_;
};

}  // namespace sweptccd::gpu
