#pragma once
// A WebSocket connection's bounded send queue (docs/WEBSOCKET.md section 7):
// a FIFO of events under a message and byte cap, plus latest-wins slots
// (status, room, each forwarded pose) where a newer message replaces the
// waiting one in place. Nothing here waits; the owner decides what an
// overflow means (slow_reader for the connection's own events, a drop for a
// viewer's events of others).
//
// Threading: not thread-safe; the door's I/O thread owns it.

#include <cstddef>
#include <deque>
#include <map>
#include <memory>
#include <string>

namespace sweptccd::ws {

using Frame = std::shared_ptr<const std::string>;

class SendQueue {
 public:
  SendQueue(size_t max_messages, size_t max_bytes);
  /// Queues `frame` in order; false (nothing queued) when the FIFO would
  /// pass its caps.
  bool Push(Frame frame);
  /// Queues `frame` unless a `key` frame waits already: then it replaces
  /// that one (its place kept). Not counted against the FIFO's caps; the
  /// number of keys is the caller's to bound.
  void PushLatest(const std::string& key, Frame frame);
  /// The next frame (FIFO and latest-wins slots taken in turn when both
  /// wait), or null when empty.
  Frame Pop();
  /// Queues `frame` even beyond the caps (a fatal error's last words).
  void PushForced(Frame frame);
  bool empty() const { return fifo_.empty() && order_.empty(); }
  size_t messages() const { return fifo_.size() + order_.size(); }
  size_t fifo_bytes() const { return fifo_bytes_; }

 private:
  size_t max_messages_, max_bytes_;
  std::deque<Frame> fifo_;
  size_t fifo_bytes_ = 0;
  std::map<std::string, Frame> latest_;
  std::deque<std::string> order_;  // Keys of latest_, oldest first.
  bool latest_turn_ = false;
};

}  // namespace sweptccd::ws
