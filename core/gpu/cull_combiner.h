#pragma once
// Private to core/gpu: many pairs' swept-volume tests in one dispatch
// (issue 30). Every thread that asks (a worker of `--threads`, a daemon
// worker, any client's culler on the same resident environment) queues its
// capsules; when no dispatch is running, the thread that finds its request
// still waiting takes every queued request (up to kMaxCapsules capsules),
// sends them in one dispatch, and hands each requester its slice of the
// answers. So while the GPU answers one dispatch, the next one gathers
// everything asked meanwhile: the more pairs in flight, the fewer and wider
// the dispatches, with no waiting added when only one pair asks. Optionally
// (SetGather) the thread that dispatches first waits, up to a window, until
// a given number of requests are queued.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <mutex>
#include <vector>

#include "core/gpu/cull_dispatch.h"
#include "core/gpu/gl_context.h"
#include "core/gpu/gpu_culler.h"

namespace sweptccd::gpu {

namespace internal {

class CullCombiner {
 public:
  /// The most capsules one dispatch takes (a request larger than that goes
  /// alone).
  static constexpr size_t kMaxCapsules = 1 << 16;

  CullCombiner(GlContext* context, CullDispatch* dispatch)
      : context_(*context), dispatch_(*dispatch) {}

  /// Tests capsules[0, n) in a dispatch shared with whatever else is queued;
  /// answers[i] as CullDispatch::Run writes it. Thread-safe. Throws GpuError
  /// (every request of a failed dispatch gets the error).
  void Cull(const GpuCapsule* capsules, size_t n, uint32_t* answers);

  /// The thread that dispatches waits until `requests` are queued or
  /// `window` has passed (requests <= 1: never waits; the default).
  void SetGather(int requests, std::chrono::microseconds window);

  DispatchStats stats() const;

 private:
  struct Request {
    const GpuCapsule* capsules;
    size_t n;
    uint32_t* answers;
    bool done = false;
    std::exception_ptr error;
  };
  // Sends `batch` (taken under the lock, sent without it).
  void Dispatch(const std::vector<Request*>& batch);

  GlContext& context_;
  CullDispatch& dispatch_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Request*> queued_;
  bool dispatching_ = false;  // A thread is sending a dispatch.
  int gather_requests_ = 1;
  std::chrono::microseconds gather_window_{0};
  DispatchStats stats_;
  // The dispatching thread's arrays (one dispatching thread at a time).
  std::vector<GpuCapsule> staging_;
  std::vector<uint32_t> answers_;
};

}  // namespace internal
}  // namespace sweptccd::gpu
