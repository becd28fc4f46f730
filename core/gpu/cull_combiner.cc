#include "core/gpu/cull_combiner.h"

#include <algorithm>
#include <cstring>

namespace sweptccd::gpu::internal {

void CullCombiner::SetGather(int requests, std::chrono::microseconds window) {
  std::lock_guard<std::mutex> lock(mutex_);
  gather_requests_ = std::max(1, requests);
  gather_window_ = window;
  changed_.notify_all();  // A thread gathering under the old rule looks again.
}

DispatchStats CullCombiner::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

void CullCombiner::Cull(const GpuCapsule* capsules, size_t n, uint32_t* answers) {
  if (n == 0) return;
  Request request{capsules, n, answers, false, nullptr};
  std::unique_lock<std::mutex> lock(mutex_);
  queued_.push_back(&request);
  changed_.notify_all();  // A dispatching thread may be gathering.
  while (!request.done) {
    if (dispatching_) {
      changed_.wait(lock);
      continue;
    }
    // No dispatch running: this thread sends what is queued.
    dispatching_ = true;
    if (gather_requests_ > 1) {
      changed_.wait_for(lock, gather_window_,
                        [&] { return queued_.size() >= static_cast<size_t>(gather_requests_); });
    }
    std::vector<Request*> batch;
    size_t total = 0;
    while (!queued_.empty() && (batch.empty() || total + queued_.front()->n <= kMaxCapsules)) {
      total += queued_.front()->n;
      batch.push_back(queued_.front());
      queued_.pop_front();
    }
    lock.unlock();
    Dispatch(batch);
    lock.lock();
    ++stats_.dispatches;
    stats_.requests += static_cast<int64_t>(batch.size());
    stats_.capsules += static_cast<int64_t>(total);
    stats_.largest = std::max<int64_t>(stats_.largest, static_cast<int64_t>(total));
    stats_.most_requests =
        std::max<int64_t>(stats_.most_requests, static_cast<int64_t>(batch.size()));
    for (Request* r : batch) r->done = true;
    dispatching_ = false;
    changed_.notify_all();
  }
  if (request.error) std::rethrow_exception(request.error);
}

void CullCombiner::Dispatch(const std::vector<Request*>& batch) {
  size_t total = 0;
  for (const Request* r : batch) total += r->n;
  staging_.resize(total);
  answers_.assign(total, 0u);
  size_t at = 0;
  for (const Request* r : batch) {
    std::memcpy(staging_.data() + at, r->capsules, r->n * sizeof(GpuCapsule));
    at += r->n;
  }
  try {
    context_.Run([&] { dispatch_.Run(staging_.data(), total, answers_.data()); });
  } catch (...) {
    const std::exception_ptr error = std::current_exception();
    for (Request* r : batch) r->error = error;
    return;
  }
  at = 0;
  for (Request* r : batch) {
    std::memcpy(r->answers, answers_.data() + at, r->n * sizeof(uint32_t));
    at += r->n;
  }
}

}  // namespace sweptccd::gpu::internal
