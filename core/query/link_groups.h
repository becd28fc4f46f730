#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): link
// groups, the hierarchical link bounds of a large skeleton. A group is a
// subtree of the kinematic tree (a hand, a finger, a foot, an arm); with the
// `articulated` model, one ball around the group root's origin holds the
// whole-pair swept capsule of every link of the group, so a group whose ball
// meets no triangle leaves every one of its links culled for the pair (the
// answer the links' own capsules give) without composing their poses.

#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "core/query/link_capsule.h"

namespace sweptccd::internal {

/// The groups of one skeleton: every link that has a parent and a subtree of
/// at least kMinLinks links roots one, except a link whose only child roots
/// one (a chain adds a link and a wider ball). Groups nest: a forearm's holds
/// the hand's links, each finger is its own. Immutable; built once per
/// engine.
class LinkGroups {
 public:
  static constexpr int kMinLinks = 4;

  explicit LinkGroups(const Skeleton& skeleton);

  bool empty() const { return num_groups_ == 0; }
  int num_groups() const { return num_groups_; }
  /// Whether `link` roots a group.
  bool IsRoot(LinkIndex link) const { return is_root_[link]; }
  /// The links of the subtree rooted at `link` (itself first), in preorder.
  const LinkIndex* begin(LinkIndex link) const { return &preorder_[position_[link]]; }
  const LinkIndex* end(LinkIndex link) const {
    return &preorder_[position_[link]] + subtree_size_[link];
  }
  /// Every link, parents before their descendants (preorder).
  const std::vector<LinkIndex>& preorder() const { return preorder_; }
  /// The children of `link`, in index order.
  const std::vector<LinkIndex>& children(LinkIndex link) const { return children_[link]; }
  /// The outermost groups narrow enough for a ball to clear them: roots
  /// whose subtree reaches at most kTopReachM at rest (from the root's
  /// origin, each child's origin taken within its parent's extent: sum of
  /// extents down a chain, plus the last radius; an estimate, which decides
  /// only which groups QueryRun tries first) and that no such root holds,
  /// in preorder: a forearm's (the hand), not the upper body's nor each
  /// finger's. 0.6 m: on the full-body skeleton a forearm's group reaches
  /// 0.44 m at rest and its ball (from a child of the root) about 0.3 m; the
  /// groups above it reach 0.8 m and more, past what a ball may be
  /// (QueryRun's 0.5 m), and gain nothing from being tried first.
  static constexpr double kTopReachM = 0.6;
  const std::vector<LinkIndex>& top_roots() const { return top_roots_; }

 private:
  std::vector<LinkIndex> preorder_;
  std::vector<std::vector<LinkIndex>> children_;
  std::vector<int> position_;      // By link: its place in preorder_.
  std::vector<int> subtree_size_;  // By link, itself included.
  std::vector<bool> is_root_;
  std::vector<LinkIndex> top_roots_;
  int num_groups_ = 0;
};

/// The reach of every link's subtree for one pair (`articulated` only): for
/// link j, an upper bound on the distance from j's origin at s = 0.5 (as
/// PairMotion composes it) to any point of the whole-pair swept capsule
/// (SweptBounds::Over(l, 0, 1), tolerance excluded) of any link l of j's
/// subtree: reach(j) = max(extent_j + radius_j + g_j, max over children c of
/// lever_c + reach(c)), g_j an upper bound on the first-order growth over
/// [0, 1] (PairMotion::PairGrowthUpper: SweepRadius, never below the
/// capsule's growth, where the link's motion is complete, and a bound on it
/// from HalfAngleUpper where it is not, so a group's links need not be
/// finished to be cleared) and lever_c
/// the child's offset bound (PairMotion::lever: SPEC 3's c, interpolated
/// linearly, stays within it). Needs no pose composed. O(links). *growth
/// gets every link's g_j.
void SubtreeReach(const LinkGroups& groups, const Skeleton& skeleton, const PairMotion& motion,
                  std::vector<double>* reach, std::vector<double>* growth);

/// Where the ball of the group rooted at `root` is centred: a link d of the
/// group (its origin at s = 0.5), and in *radius an upper bound on the
/// distance from there to any point of any member's whole-pair capsule
/// (tolerance excluded, as reach). From the root, d moves to the child c
/// with the largest lever_c + reach(c) while that narrows the bound:
/// radius(c) = max(reach(c), up(c)), up(c) = max(own_c(d), lever_c + up(d),
/// apart(c, s) + reach(s) over d's other children s), up(root) = 0, where
/// own_c(d) = max over d's segment ends e and c's offsets c_0, c_1 of
/// |c_k - e| + radius_d + g_d and apart(c, s) = max(|c_0 - s_0|, |c_1 -
/// s_1|) (norms rounded up): a member in c's subtree is within reach(c) of
/// c's origin; d's own capsule and d's other children's origins are
/// interpolated in d's frame as c's origin is (SPEC 3: c is linear in s), so
/// their distance from it peaks at s = 0 or 1; what lies above d is reached
/// through d's origin, lever_c away. A finger's ball moves from its
/// metacarpal's origin (at the wrist) to its knuckle, a forearm's to the
/// wrist: about half the radius. At most kMaxCentreSteps steps (so O(steps x children),
/// and a group's whole chain is never walked); needs no pose composed.
constexpr int kMaxCentreSteps = 8;
LinkIndex BallCentre(const LinkGroups& groups, const Skeleton& skeleton, const PairMotion& motion,
                     const std::vector<double>& reach, const std::vector<double>& growth,
                     LinkIndex root, double* radius);

/// The ball of a group: centred at the origin of `centre` at s = 0.5 (as
/// BallCentre gives it; its ends must be composed), radius `radius` (ditto)
/// + `tolerance_m` (the query's, which every capsule carries) + 4 rounding
/// slacks of the motion (the two composed points) + BoxPad of the motion's
/// scale (far above the rounding of these sums and of the distance tests).
/// It holds the whole-pair capsule of every link of the group, so a
/// triangle that no test finds within it is not found within any of them.
LinkCapsule GroupBall(const PairMotion& motion, LinkIndex centre, double radius,
                      double tolerance_m);
/// A ball holding the same capsules with no pose composed nor motion
/// finished (the one QueryRun::ClearGroups tests): centred at the midpoint
/// m of the centre link's origins in `pose0` and `pose1` (the poses the
/// motion was built from), radius `radius` + V / 2 (V the centre's origin
/// speed bound, PairMotion::OriginSpeedUpper: the origin's SPEC 3 path from
/// o(0) to o(1) is at most V long, so o(0.5) is within V / 2 of m) +
/// `tolerance_m` + 8 rounding slacks (GroupBall's 4; the composed origin at
/// 0.5 and the poses' origins against the exact motion's) + BoxPad.
/// docs/DESIGN.md, "Hierarchical link bounds".
LinkCapsule GroupBallAtMidpoint(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                                LinkIndex centre, double radius, double tolerance_m);

/// The ball of a top-level group from its members' bone lengths, which
/// needs no member's motion begun below the root (issue 31: QueryRun defers
/// them, PairMotion's `deferred`, and a quiet pair never begins them).
/// Centred as GroupBallAtMidpoint at the child d of the root whose subtree
/// reaches farthest (d's motion is begun here: its offsets and speed bound),
/// radius R (+ GroupBallAtMidpoint's V_d / 2, tolerance and slacks), R an
/// upper bound on the distance at every s from d's origin at s to any point
/// of any member at the same s:
/// - a member l below a child c of the root: |p_c(s) - p_d(s)| = |c_c(s) -
///   c_d(s)| (both offsets in the root's frame, interpolated linearly, so
///   at most the larger at s = 0 or 1, where it is the world |p_c - p_d|),
///   then each link on the way down from c to l adds at most its lever
///   (|c_j(s)| <= max(|c_j0|, |c_j1|) = the world |p_j - p_k| at an end),
///   and l's capsule extent + radius: stat(c) = max(extent_c + radius_c,
///   max over c's children j of lever_j + stat(j));
/// - the root's own capsule: max over its segment ends e of |e - c_d(s)|
///   (at s = 0 or 1, as OwnFromChild) + its radius.
/// Every point of the group's swept volume is so within R + V_d / 2 of d's
/// midpoint. It need not hold the members' whole-pair capsules (their
/// first-order growth can be far wider than the motion): a group it clears
/// may hold a link whose own capsules would have been searched, which a
/// query then never descends (its exact swept volume meets nothing).
/// *stat: scratch, by link (sized to the skeleton). `root` must be begun.
LinkCapsule StaticGroupBall(const LinkGroups& groups, const Skeleton& skeleton, PairMotion* motion,
                            const Pose& pose0, const Pose& pose1, LinkIndex root,
                            double tolerance_m, std::vector<double>* stat);

}  // namespace sweptccd::internal
