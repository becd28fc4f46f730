#pragma once
// One spare object per thread and type, for work that fills the same arrays
// call after call (a query's per-link arrays, an entity answer's lists):
// a call takes the thread's spare, or a new one when it is taken already (a
// call running inside another on the same thread), and gives it back when
// it ends, so only capacity carries from one call to the next. Nothing is
// shared between threads.

#include <cstddef>
#include <memory>
#include <vector>

namespace sweptccd {

/// Frees *v when its capacity passes `most` elements (a rare large call
/// should not pin its memory for the thread's life).
template <class T>
void FreeIfAbove(std::vector<T>* v, size_t most) {
  if (v->capacity() > most) std::vector<T>().swap(*v);
}

/// Holds this thread's spare T for one call (see above). T must be default
/// constructible; the caller clears or overwrites what it reads.
template <class T>
class ThreadSpare {
 public:
  ThreadSpare() : t_(Slot() != nullptr ? std::move(Slot()) : std::make_unique<T>()) {}
  /// Gives it back when the thread's slot is empty (else it is freed).
  ~ThreadSpare() {
    if (Slot() == nullptr) Slot() = std::move(t_);
  }
  ThreadSpare(const ThreadSpare&) = delete;
  ThreadSpare& operator=(const ThreadSpare&) = delete;

  T& operator*() { return *t_; }
  T* operator->() { return t_.get(); }

 private:
  static std::unique_ptr<T>& Slot() {
    thread_local std::unique_ptr<T> slot;
    return slot;
  }
  std::unique_ptr<T> t_;
};

}  // namespace sweptccd
