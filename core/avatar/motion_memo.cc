#include "core/avatar/motion_memo.h"

#include <cstring>

namespace sweptccd {

MotionMemo::MotionMemo(const PairMotion& motion, size_t max_times)
    : motion_(motion), max_times_(max_times > 0 ? max_times : 1) {}

MotionMemo::Slot* MotionMemo::SlotsAt(double s) {
  uint64_t key;
  std::memcpy(&key, &s, sizeof key);
  const size_t n = static_cast<size_t>(motion_.num_links());
  auto it = times_.find(key);
  if (it != times_.end()) return slots_.data() + it->second * n;
  if (times_.size() >= max_times_) {
    times_.clear();
    blocks_used_ = 0;
  }
  const size_t block = blocks_used_++;
  if (slots_.size() < (block + 1) * n) {
    slots_.resize((block + 1) * n);
  } else {
    for (size_t i = block * n; i < (block + 1) * n; ++i) {
      slots_[i].have_pose = false;
      slots_[i].have_segment = false;
    }
  }
  times_.emplace(key, block);
  return slots_.data() + block * n;
}

void MotionMemo::ComposePose(Slot* slots, int link, double s) {
  // Up to the first ancestor already composed (or the chain's top), then
  // down: each step is PoseAt's, from the parent's pose as PoseAt has it.
  chain_.clear();
  for (int k = link; k >= 0 && !slots[k].have_pose; k = motion_.motion_parent(k)) {
    chain_.push_back(k);
  }
  for (size_t i = chain_.size(); i-- > 0;) {
    const int k = chain_[i];
    const int parent = motion_.motion_parent(k);
    Slot& slot = slots[k];
    slot.pose = motion_.PoseFromParent(k, s, parent >= 0 ? slots[parent].pose : LinkPose());
    slot.have_pose = true;
  }
}

void MotionMemo::SegmentAt(int link, double s, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB) {
  Slot* slots = SlotsAt(s);
  Slot& slot = slots[link];
  if (!slot.have_segment) {
    if (!slot.have_pose) ComposePose(slots, link, s);
    motion_.SegmentOfPose(link, slot.pose, &slot.a, &slot.b);
    slot.have_segment = true;
  }
  *p_WA = slot.a;
  *p_WB = slot.b;
}

void MotionMemo::SweptCapsule(int link, double s0, double s1, Eigen::Vector3d* p_WA,
                              Eigen::Vector3d* p_WB, double* growth) {
  // The same segments, in the same order, as PairMotion::SweptCapsule.
  Eigen::Vector3d a0, b0, a1, b1, am, bm;
  SegmentAt(link, s0, &a0, &b0);
  SegmentAt(link, s1, &a1, &b1);
  SegmentAt(link, 0.5 * (s0 + s1), &am, &bm);
  motion_.SweptCapsuleFromSegments(link, s0, s1, a0, b0, a1, b1, am, bm, p_WA, p_WB, growth);
}

}  // namespace sweptccd
