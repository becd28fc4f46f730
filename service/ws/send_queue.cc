#include "service/ws/send_queue.h"

namespace sweptccd::ws {

SendQueue::SendQueue(size_t max_messages, size_t max_bytes)
    : max_messages_(max_messages), max_bytes_(max_bytes) {}

bool SendQueue::Push(Frame frame) {
  if (fifo_.size() + 1 > max_messages_ || fifo_bytes_ + frame->size() > max_bytes_) return false;
  fifo_bytes_ += frame->size();
  fifo_.push_back(std::move(frame));
  return true;
}

void SendQueue::PushForced(Frame frame) {
  fifo_bytes_ += frame->size();
  fifo_.push_back(std::move(frame));
}

void SendQueue::PushLatest(const std::string& key, Frame frame) {
  auto [it, inserted] = latest_.try_emplace(key, frame);
  if (inserted) {
    order_.push_back(key);
  } else {
    it->second = std::move(frame);
  }
}

Frame SendQueue::Pop() {
  const bool take_latest = !order_.empty() && (fifo_.empty() || latest_turn_);
  latest_turn_ = !latest_turn_;
  if (take_latest) {
    const auto it = latest_.find(order_.front());
    Frame f = std::move(it->second);
    latest_.erase(it);
    order_.pop_front();
    return f;
  }
  if (fifo_.empty()) return nullptr;
  Frame f = std::move(fifo_.front());
  fifo_.pop_front();
  fifo_bytes_ -= f->size();
  return f;
}

}  // namespace sweptccd::ws
