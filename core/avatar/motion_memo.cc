#include "core/avatar/motion_memo.h"

#include <algorithm>
#include <cstring>

namespace sweptccd {

MotionMemo::MotionMemo(const PairMotion& motion, size_t max_times)
    : motion_(&motion), max_times_(max_times > 0 ? max_times : 1) {}

void MotionMemo::Rebind(const PairMotion& motion) {
  motion_ = &motion;
  times_.clear();
  blocks_used_ = 0;
  swept_times_.clear();
  swept_blocks_used_ = 0;
  last_swept_ = nullptr;
}

MotionMemo::Slot* MotionMemo::SlotsAt(double s) {
  uint64_t key;
  std::memcpy(&key, &s, sizeof key);
  const size_t n = static_cast<size_t>(motion_->num_links());
  auto it = times_.find(key);
  if (it != times_.end()) return slots_.data() + it->second * n;
  if (times_.size() >= max_times_) {
    times_.clear();
    blocks_used_ = 0;
  }
  const size_t block = blocks_used_++;
  // Slots kept from earlier use are emptied (after Rebind to a motion with
  // another link count, a block may overlap old slots and new ones).
  const size_t kept = std::min(slots_.size(), (block + 1) * n);
  for (size_t i = block * n; i < kept; ++i) {
    slots_[i].have_pose = false;
    slots_[i].have_segment = false;
  }
  if (slots_.size() < (block + 1) * n) slots_.resize((block + 1) * n);
  times_.emplace(key, block);
  return slots_.data() + block * n;
}

void MotionMemo::ComposePose(Slot* slots, LinkIndex link, double s) {
  // Up to the first ancestor already composed (or the chain's top), then
  // down: each step is PoseAt's, from the parent's pose as PoseAt has it.
  chain_.clear();
  for (LinkIndex k = link; k.is_valid() && !slots[k].have_pose; k = motion_->motion_parent(k)) {
    chain_.push_back(k);
  }
  for (size_t i = chain_.size(); i-- > 0;) {
    const LinkIndex k = chain_[i];
    const LinkIndex parent = motion_->motion_parent(k);
    Slot& slot = slots[k];
    slot.pose = motion_->PoseFromParent(k, s, parent.is_valid() ? slots[parent].pose : LinkPose());
    slot.have_pose = true;
  }
}

void MotionMemo::SegmentAt(LinkIndex link, double s, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB) {
  if (s == 0.0 || s == 0.5 || s == 1.0) {
    motion_->SegmentAt(link, s, p_WA, p_WB);  // A look-up there (the same bits).
    return;
  }
  Slot* slots = SlotsAt(s);
  Slot& slot = slots[link];
  if (!slot.have_segment) {
    if (!slot.have_pose) ComposePose(slots, link, s);
    motion_->SegmentOfPose(link, slot.pose, &slot.a, &slot.b);
    slot.have_segment = true;
  }
  *p_WA = slot.a;
  *p_WB = slot.b;
}

MotionMemo::SweptSlot* MotionMemo::SweptSlotsAt(double s0, double s1) {
  SweptKey key;
  std::memcpy(&key.s0, &s0, sizeof key.s0);
  std::memcpy(&key.s1, &s1, sizeof key.s1);
  if (last_swept_ != nullptr && key == last_swept_key_) return last_swept_;
  const size_t n = static_cast<size_t>(motion_->num_links());
  auto it = swept_times_.find(key);
  if (it == swept_times_.end()) {
    if (swept_times_.size() >= max_times_) {
      swept_times_.clear();
      swept_blocks_used_ = 0;
    }
    const size_t block = swept_blocks_used_++;
    // As SlotsAt: slots kept from earlier use are emptied.
    const size_t kept = std::min(swept_.size(), (block + 1) * n);
    for (size_t i = block * n; i < kept; ++i) swept_[i].have = false;
    if (swept_.size() < (block + 1) * n) swept_.resize((block + 1) * n);
    it = swept_times_.emplace(key, block).first;
  }
  last_swept_key_ = key;
  last_swept_ = swept_.data() + it->second * n;
  return last_swept_;
}

void MotionMemo::SweptCapsule(LinkIndex link, double s0, double s1, Eigen::Vector3d* p_WA,
                              Eigen::Vector3d* p_WB, double* growth) {
  SweptSlot& slot = SweptSlotsAt(s0, s1)[link];
  if (!slot.have) {
    // The same segments, in the same order, as PairMotion::SweptCapsule.
    Eigen::Vector3d a0, b0, a1, b1, am, bm;
    SegmentAt(link, s0, &a0, &b0);
    SegmentAt(link, s1, &a1, &b1);
    SegmentAt(link, 0.5 * (s0 + s1), &am, &bm);
    motion_->SweptCapsuleFromSegments(link, s0, s1, a0, b0, a1, b1, am, bm, &slot.a, &slot.b,
                                      &slot.growth);
    slot.have = true;
  }
  *p_WA = slot.a;
  *p_WB = slot.b;
  *growth = slot.growth;
}

}  // namespace sweptccd
