#pragma once
// Memoised segments and swept capsules of one PairMotion, for callers that
// ask for many links at the same normalised times (the descents of
// core/world, where every link is halved over the same intervals).

#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/avatar/motion.h"

namespace sweptccd {

/// Answers SegmentAt and SweptCapsule of a PairMotion bit for bit as the
/// motion does, composing each link's pose at a given s once (ancestors
/// included: a link's pose at s is composed from its parent's, kept). Times
/// are keyed by their bits (-0.0 is not 0.0). The memo is emptied when it
/// holds `max_times` times; callers that visit times in order find the
/// recent ones kept. Not thread-safe: one memo per thread. The motion must
/// outlive the memo.
class MotionMemo {
 public:
  explicit MotionMemo(const PairMotion& motion, size_t max_times = 1024);

  const PairMotion& motion() const { return *motion_; }
  /// Forgets every time and answers for `motion` from now on, keeping the
  /// memory (a caller answering pair after pair allocates once).
  void Rebind(const PairMotion& motion);

  /// As PairMotion::SegmentAt (the same bits).
  void SegmentAt(int link, double s, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB);
  /// As PairMotion::SweptCapsule (the same bits).
  void SweptCapsule(int link, double s0, double s1, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB,
                    double* growth);

 private:
  struct Slot {
    LinkPose pose;
    Eigen::Vector3d a{0, 0, 0}, b{0, 0, 0};
    bool have_pose = false;
    bool have_segment = false;
  };
  // The slots of every link at s (num_links() of them, created empty on
  // first use); valid until the next call.
  Slot* SlotsAt(double s);
  // Fills slots[link].pose, and that of each ancestor not yet there.
  void ComposePose(Slot* slots, int link, double s);

  const PairMotion* motion_;
  size_t max_times_;
  // Time -> its block of num_links() slots in slots_. Blocks are reused
  // after the memo is emptied (no allocation per time once warm).
  std::unordered_map<uint64_t, size_t> times_;
  std::vector<Slot> slots_;
  size_t blocks_used_ = 0;
  std::vector<int> chain_;  // Scratch of ComposePose.
};

}  // namespace sweptccd
