#pragma once
// A fixed set of worker threads that answer a batch of independent items
// (`--threads N` of `sweptccd query`, `world`, `bench`): the caller hands a
// count and a function, the workers take the items one by one, and Run
// returns when every item is done. Results go where the function puts them
// (by index), so the caller writes them in input order whatever the number
// of threads.

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace sweptccd {

/// The default of `--threads`: std::thread::hardware_concurrency(), at least 1.
int DefaultThreadCount();

class WorkerPool {
 public:
  /// `threads` >= 1 workers: the calling thread of Run and threads - 1
  /// started here. Throws std::invalid_argument for threads < 1, and
  /// std::system_error when a thread cannot start (those started are joined
  /// first).
  explicit WorkerPool(int threads);
  /// Joins the workers (Run must not be running).
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int size() const { return static_cast<int>(threads_.size()) + 1; }

  /// Calls work(i, worker) once for every i in [0, count), on the workers
  /// (worker in [0, size()): 0 is the calling thread; one worker runs one
  /// item at a time, so per-worker state indexed by `worker` needs no lock).
  /// Returns when all are done; rethrows the first exception an item threw
  /// (the items not yet started are then skipped). One Run at a time.
  void Run(size_t count, const std::function<void(size_t, int)>& work);

 private:
  void Serve(int worker);
  void Work(int worker);
  void Stop();  // Ends and joins the started threads.

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  uint64_t generation_ = 0;  // Bumped by each Run.
  bool stop_ = false;
  const std::function<void(size_t, int)>* work_ = nullptr;
  size_t count_ = 0;
  size_t next_ = 0;  // Next item to take (under mutex_).
  int busy_ = 0;     // Helpers still in the current Run.
  std::exception_ptr error_;
};

}  // namespace sweptccd
