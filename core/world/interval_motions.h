#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): an avatar's
// motions over its sample intervals with their memos (its links' poses at
// the times asked), kept across answers: every pair of every other avatar
// whose window meets interval k asks for the same motion.

#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/motion_memo.h"
#include "core/geometry/bvh.h"
#include "core/world/entity_window.h"

namespace sweptccd::world {

/// At most `max_kept` intervals are kept (the farthest goes), each memo
/// with at most 64 times (callers visit intervals in time order). Not
/// thread-safe; the entity's storage outlives it, and it outlives the
/// targets made with it.
class IntervalMotions {
 public:
  /// `link_boxes`, when not empty, holds LinkSweepBoxes(skeleton, motion
  /// of interval k, 0) for every interval k, made by the caller (who built
  /// each motion once already); LinkBoxesOf then answers from it without
  /// building the motion.
  /// `near_boxes`, likewise, NearLinkBoxes (near_link_boxes.h) of every
  /// interval with margin `near_margin`.
  explicit IntervalMotions(const AvatarWindow& entity, size_t max_kept = 4,
                           std::vector<std::vector<Aabb>> link_boxes = {},
                           std::vector<std::vector<Aabb>> near_boxes = {}, double near_margin = 0);
  IntervalMotions(const IntervalMotions&) = delete;
  IntervalMotions& operator=(const IntervalMotions&) = delete;
  /// The memo of the motion from sample k to k + 1 (k + 1 clamped).
  MotionMemo& MemoOf(int k);
  /// That motion (valid until MemoOf or MotionOf asks for an interval not
  /// kept while this one is the farthest).
  const PairMotion& MotionOf(int k) { return MemoOf(k).motion(); }
  /// LinkSweepBoxes(skeleton, MotionOf(k), 0): the caller's when given
  /// (valid as long as this), else computed once per interval kept (valid
  /// as MotionOf's answer).
  const std::vector<Aabb>& LinkBoxesOf(int k);
  /// NearLinkBoxes(skeleton, memo of MotionOf(k), margin): the caller's
  /// when given with this margin (valid as long as this), else computed once
  /// per interval kept (valid as MotionOf's answer).
  const std::vector<Aabb>& NearLinkBoxesOf(int k, double margin);

 private:
  struct Held {
    PairMotion motion;
    MotionMemo memo;               // Over `motion`.
    std::vector<Aabb> link_boxes;  // LinkSweepBoxes of `motion`; empty: not yet.
    std::vector<Aabb> near_boxes;  // NearLinkBoxes of `motion`; empty: not yet.
    double near_margin = 0;        // Theirs.
    Held(const AvatarWindow& e, int k, int k1);
  };
  AvatarWindow entity_;
  size_t max_kept_;
  std::map<int, std::unique_ptr<Held>> held_;
  std::vector<std::vector<Aabb>> given_link_boxes_;  // By interval; empty: none given.
  std::vector<std::vector<Aabb>> given_near_boxes_;  // Likewise.
  double given_near_margin_ = 0;
  std::optional<MotionMemo> near_memo_;  // Composes the near boxes (rebound).
};

}  // namespace sweptccd::world
