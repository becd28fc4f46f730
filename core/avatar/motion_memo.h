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
  void SegmentAt(LinkIndex link, double s, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB);
  /// As PairMotion::SweptCapsule (the same bits), kept per (s0, s1) by
  /// their bits like the segments (callers answering one motion against
  /// several entities ask for the same intervals again).
  void SweptCapsule(LinkIndex link, double s0, double s1, Eigen::Vector3d* p_WA,
                    Eigen::Vector3d* p_WB, double* growth);

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
  void ComposePose(Slot* slots, LinkIndex link, double s);

  struct SweptSlot {
    Eigen::Vector3d a{0, 0, 0}, b{0, 0, 0};
    double growth = 0;
    bool have = false;
  };
  struct SweptKey {
    uint64_t s0, s1;
    bool operator==(const SweptKey& o) const { return s0 == o.s0 && s1 == o.s1; }
  };
  struct SweptKeyHash {
    size_t operator()(const SweptKey& k) const {
      return std::hash<uint64_t>()(k.s0 * 0x9E3779B97F4A7C15ull ^ k.s1);
    }
  };
  // The swept slots of every link over [s0, s1] (num_links() of them,
  // created empty on first use); valid until the next call.
  SweptSlot* SweptSlotsAt(double s0, double s1);

  const PairMotion* motion_;
  size_t max_times_;
  // Time -> its block of num_links() slots in slots_. Blocks are reused
  // after the memo is emptied (no allocation per time once warm).
  std::unordered_map<uint64_t, size_t> times_;
  std::vector<Slot> slots_;
  size_t blocks_used_ = 0;
  std::vector<LinkIndex> chain_;  // Scratch of ComposePose.
  // (s0, s1) -> its block of num_links() swept slots, kept like times_ (at
  // most max_times_ intervals, then emptied); the last one asked for is
  // remembered, since callers ask for every link over one interval in turn.
  std::unordered_map<SweptKey, size_t, SweptKeyHash> swept_times_;
  std::vector<SweptSlot> swept_;
  size_t swept_blocks_used_ = 0;
  SweptKey last_swept_key_{0, 0};
  SweptSlot* last_swept_ = nullptr;
};

}  // namespace sweptccd
