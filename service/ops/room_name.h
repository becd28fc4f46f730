#pragma once
// The room's name as the daemon tells it (docs/DEPLOY.md "Which room a
// server holds"): the configured `room` at start, then the allocated
// GameServer's `sweptccd.dev/room` label once the Agones SDK sidecar reports
// one (AgonesLifecycle). Read by the WebSocket door (hello, status) and the
// metrics (the `room` label) on their own threads. Header only: the door's
// library (service/ws/) reads it too.

#include <mutex>
#include <string>

namespace sweptccd {

class RoomName {
 public:
  explicit RoomName(std::string name) : name_(std::move(name)) {}
  std::string Get() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return name_;
  }
  /// True when `name` differs from the current name (then it replaces it).
  /// The caller checks the id rule first.
  bool Set(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (name == name_) return false;
    name_ = name;
    return true;
  }

 private:
  mutable std::mutex mutex_;
  std::string name_;
};

}  // namespace sweptccd
