#pragma once
// The motion between two poses (SPEC section 3) and bounds on how far each
// link can travel over a time interval.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/typed_index.h"

namespace sweptccd {

enum class MotionModel { kArticulated, kIndependent };

/// "articulated" or "independent"; nullopt for anything else.
std::optional<MotionModel> ParseMotionModel(const std::string& text);
const char* MotionModelName(MotionModel model);

/// Shortest-arc spherical interpolation of unit quaternions (SPEC section 3):
/// q1 is replaced by -q1 when dot(q0, q1) < 0. Returns a unit quaternion.
Eigen::Quaterniond Slerp(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1, double s);

/// Rotation angle (radians, in [0, pi]) of the shortest arc from q0 to q1: the
/// constant angular speed of Slerp per unit of s.
double SlerpAngle(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1);

namespace internal {

/// The sign (-1, 0 or 1) of the exact dot product of two 4-vectors (SPEC 3's
/// shortest-arc rule, dot(q0, q1) < 0, decided exactly even for a turn of
/// exactly 180 degrees, whose rounded dot is noise around 0). Exact while no
/// component exceeds 2^500 and every product a_k b_k is 0 or at least 2^-900
/// in magnitude (its parts clear of underflow): Slerp and PairMotion use it
/// for unit quaternions whose components below 2^-450 were set to 0
/// (FlushTinyComponents, pose.h; validated poses, object samples and
/// relative rotations all are).
int DotSign(const double a[4], const double b[4]);

/// The upper ends of PairMotion's two growth bounds over [s0, s1], bit for
/// bit the interval expressions they replace (the twins in
/// tests/core/avatar/motion_test.cc), without the lower ends. Inputs are the
/// bounds' upper ends: non-negative and finite; 0 <= s0 <= s1 <= 1.
/// First order: (speed + angular * extent) * (s1 - s0) / 2 + slack.
double FirstOrderGrowth(double speed, double angular, double extent, double slack, double s0,
                        double s1);
/// FirstOrderGrowth(speed, angular, extent, slack, 0, 1), bit for bit (the
/// same steps, its half width a constant): the whole pair's growth, which
/// PairMotion::PairGrowthUpper computes for every link of a query.
double FirstOrderGrowthOverPair(double speed, double angular, double extent, double slack);
/// Second order: chord / 2 + (s1 - s0)^2 / 4 * (accel + (angular_accel +
/// angular^2) * extent) + 4 slack.
double SecondOrderGrowth(double chord, double accel, double angular_accel, double angular,
                         double extent, double slack, double s0, double s1);

/// A link's bounds over the pair (upper ends, per unit s): origin speed,
/// angular speed, origin acceleration, angular acceleration.
struct LinkBounds {
  double speed = 0, angular = 0, accel = 0, angular_accel = 0;
};
/// PairMotion's bounds of one link in interval arithmetic, from its own
/// slerp half angle (radians, >= 0), the upper ends of its own speed
/// |p1 - p0| and of its lever max(|p0|, |p1|) (positions relative to its
/// parent; both >= 0), and its parent's bounds (null: it moves on its own,
/// and the lever is unused).
LinkBounds LinkBoundsByIntervals(double half_angle, double own_speed, double lever,
                                 const LinkBounds* parent);
/// The same bits from the upper ends alone, as the growth bounds above: false
/// (leaving *out) where a step does not stay finite.
bool LinkBoundsByUpperEnds(double half_angle, double own_speed, double lever,
                           const LinkBounds* parent, LinkBounds* out);
/// LinkBoundsByUpperEnds's speed and angular alone, the same steps (so the
/// same bits for the same inputs, and never below them for larger ones:
/// every step is a rounded-up sum or product of non-negative numbers, which
/// is nondecreasing in each operand). Infinite where a step does not stay
/// finite (an infinite bound is still an upper bound).
void FirstOrderBoundsUpper(double half_angle, double own_speed, double lever,
                           const LinkBounds* parent, double* speed, double* angular);

/// The largest slerp half angle PairMotion can compute for a link (the
/// shortest arc: pi / 2, plus far more than its rounding).
constexpr double kMaxHalfAngle = 1.5707963267948966 + 1e-9;
/// An upper bound, without atan2, on the slerp half angle PairMotion computes
/// for a link whose relative rotations at the two ends are the products `a`
/// and `b` (conj(q_parent) q_link, before their normalisation): with t =
/// |a.b| / (|a| |b|) the cosine of the shortest-arc angle psi between the
/// normalised a and b, psi = acos(t) <= 2 tan(psi / 2) = 2 sqrt((1 - t) /
/// (1 + t)), evaluated at t - 1e-14 (t's rounding is below 2e-15 while |a|
/// and |b| are within 1e-9 of 1) and widened by 1e-12 rad (the rounding of
/// the normalisation, the flush of tiny components and atan2, all below
/// 1e-14 rad), never above kMaxHalfAngle; kMaxHalfAngle when a or b is
/// farther from unit length. docs/DESIGN.md, "Hierarchical link bounds".
double HalfAngleUpper(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace internal

/// The interpolated motion of every link of a skeleton between two valid poses
/// (normalised quaternions). Immutable after construction; const methods are
/// safe to call from several threads.
class PairMotion {
 public:
  /// Preconditions: both poses have skeleton.num_links() links with unit
  /// quaternions and finite numbers (as ValidateAndNormalizePose leaves them).
  PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, MotionModel model);

  /// The arrays of a motion no longer needed, for the next one to reuse (a
  /// query keeps one per thread, so a pair allocates nothing for its
  /// motion). Holds no motion; its contents are overwritten. Like any
  /// vector, used by one thread at a time.
  struct Storage;
  /// As above, built in `storage`'s arrays (taken; null: fresh ones). The
  /// same motion, bit for bit.
  PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, MotionModel model,
             Storage* storage);
  /// Whether construction composes every link's pose and segment at s = 0,
  /// 0.5 and 1 and finishes every link's motion (kAll), or leaves the ends
  /// to CompleteEnds and, with `articulated`, each child's motion to
  /// CompleteMotion, link by link (kOnDemand: a query whose link groups
  /// clear a subtree never composes or finishes it; core/query/
  /// link_groups.h). The rounding slack, coordinate scale and every link's
  /// offsets (offset) are computed for every link either way, with the same
  /// bits; so is everything else once finished.
  enum class Ends { kAll, kOnDemand };
  /// `deferred` (kOnDemand with `articulated` only; null: none): by link,
  /// non-zero for links whose motion is not even begun (QueryRun defers the
  /// members of a top-level link group below its root, which a ball from
  /// their bone lengths may clear: core/query/link_groups.h,
  /// StaticGroupBall). A deferred link must have a motion parent, and its
  /// descendants must be deferred too. Build computes only its lever (from
  /// the world positions: lever()) and what the rounding slack and
  /// coordinate scale read, the same for every link deferred or not; until
  /// BeginLink nothing else of it may be read (offset() checks; its
  /// PairGrowthUpper and OriginSpeedUpper are infinite). The poses must
  /// outlive the motion while any link is deferred (BeginLink reads them).
  PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, MotionModel model,
             Storage* storage, Ends ends, const std::vector<char>* deferred = nullptr);
  /// Begins a deferred link's motion as Build begins every other link's
  /// (its offsets, relative rotations' products, own speed, lever and upper
  /// bounds: the same bits as a motion that did not defer it). Its motion
  /// parent must be begun. Nothing for a link already begun.
  void BeginLink(LinkIndex link);
  /// Whether the link's motion is begun (always, unless deferred).
  bool LinkBegun(LinkIndex link) const { return links_[link].begun; }
  /// kOnDemand: composes the link's poses and segments at s = 0, 0.5 and 1
  /// (the same operations as kAll, so the same bits). Its motion parent's
  /// must be complete. Not const: call it before the motion is shared.
  void CompleteEnds(LinkIndex link);
  /// Whether the link's poses at s = 0, 0.5 and 1 are composed (always with
  /// kAll). PoseAt, PoseFromParent and SegmentAt at those times, and the
  /// swept capsules over intervals ending there, need them (checked).
  bool EndsReady(LinkIndex link) const { return all_ready_ || links_[link].ends_ready; }
  /// kOnDemand with `articulated` also leaves each link that has a motion
  /// parent unfinished: its offsets c_0, c_1 (offset), lever, own speed and
  /// the products of its relative rotations are computed, but not its slerp
  /// angle, sines and exact bounds; until CompleteMotion (which CompleteEnds
  /// calls) its speed and angular speed bounds are upper bounds of the exact
  /// ones built from HalfAngleUpper (PairGrowthUpper reads them). Its motion
  /// parent's motion must be complete. The same bits as kAll.
  void CompleteMotion(LinkIndex link);
  /// Whether the link's motion is complete (always with kAll). Everything
  /// that reads its bounds or composes it needs that (checked).
  bool MotionReady(LinkIndex link) const { return all_ready_ || links_[link].motion_ready; }
  /// An upper bound on SweepRadius(link, 0, 1): that, bit for bit, once the
  /// link's motion is complete; before, the same first-order growth of the
  /// link's upper bounds (infinite past 1e300). Never needs the motion.
  double PairGrowthUpper(LinkIndex link) const;
  /// PairGrowthUpper of every link, by link index, into *out (resized): the
  /// same bits, in one loop (SubtreeReach reads them all, pair after pair).
  void PairGrowthUppers(std::vector<double>* out) const;
  /// Gives the arrays back for another motion; this motion is left empty.
  /// Not const: no other thread may be reading this motion.
  void Release(Storage* storage);

  int num_links() const { return static_cast<int>(links_.size()); }
  MotionModel model() const { return model_; }

  /// World pose X_WL of every link at normalised time s in [0, 1].
  void PosesAt(double s, std::vector<LinkPose>* X_WL) const;
  /// World pose of one link at s (composes its ancestors for `articulated`,
  /// except at s = 0, 0.5 and 1, whose poses PosesAt computed once at
  /// construction: the swept capsule of every link over the whole pair needs
  /// exactly those, so a culled link costs O(1), not O(chain depth)). The
  /// same bits either way (the same operations in the same order).
  LinkPose PoseAt(LinkIndex link, double s) const;
  /// World segment (A, B) of a link at s. At s = 0, 0.5 and 1 a look-up of
  /// the segments computed at construction (the same bits).
  void SegmentAt(LinkIndex link, double s, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB) const;

  /// The link PoseAt composes `link`'s pose from (its parent with
  /// `articulated`), or an invalid index when the link moves on its own.
  LinkIndex motion_parent(LinkIndex link) const { return links_[link].parent; }
  /// The pose of `link` at s given its motion parent's pose X_WP at s (as
  /// PoseAt returns it; ignored when motion_parent(link) is invalid): the same
  /// operations in the same order as PoseAt, so the same bits. Lets a caller
  /// that needs many links at one s compose each ancestor once.
  LinkPose PoseFromParent(LinkIndex link, double s, const LinkPose& X_WP) const;
  /// World segment (A, B) of a link at pose X_WL (as PoseAt returns it): the
  /// same bits as SegmentAt.
  void SegmentOfPose(LinkIndex link, const LinkPose& X_WL, Eigen::Vector3d* p_WA,
                     Eigen::Vector3d* p_WB) const;

  /// Upper bound on |d p_WL / ds| for the link frame origin (metres per unit s).
  double origin_speed_bound(LinkIndex link) const {
    CheckMotionReady(link);
    return links_[link].bounds.speed;
  }
  /// origin_speed_bound once the link's motion is complete; before, the
  /// upper bound of it that PairGrowthUpper reads (FirstOrderBoundsUpper:
  /// never below it, infinite where a step overflows). Never needs the motion.
  double OriginSpeedUpper(LinkIndex link) const { return links_[link].bounds.speed; }
  /// Upper bound on the angular speed of the link frame (radians per unit s).
  double angular_speed_bound(LinkIndex link) const {
    CheckMotionReady(link);
    return links_[link].bounds.angular;
  }

  /// Upper bound on how far any point of link i's segment can be, at any s in
  /// [s0, s1], from where the same point of the link is at the midpoint
  /// (s0 + s1) / 2. Outward rounded and including slack for the rounding of
  /// SegmentAt, so that the swept volume of the link over [s0, s1] lies inside
  /// the capsule around SegmentAt(midpoint) with radius radius + SweepRadius.
  double SweepRadius(LinkIndex link, double s0, double s1) const;

  /// The swept bound used by queries: the segment at the midpoint of [s0, s1]
  /// and a radius growth such that the link's swept volume over [s0, s1] lies
  /// within the capsule (p_WA, p_WB, link radius + growth). The growth is the
  /// smaller of SweepRadius and a second-order bound: for every link point,
  /// |P(s) - P(mid)| <= |P(s1) - P(s0)| / 2 + (s1 - s0)^2 / 4 * max |P''|,
  /// from the chord error bound (s - s0)(s1 - s) / 2 * max |P''|.
  void SweptCapsule(LinkIndex link, double s0, double s1, Eigen::Vector3d* p_WA,
                    Eigen::Vector3d* p_WB, double* growth) const;
  /// As SweptCapsule, given the segments at s0 (a0, b0) and s1 (a1, b1) as
  /// SegmentAt computes them (time slicing reuses them from the parent).
  void SweptCapsuleFromEnds(LinkIndex link, double s0, double s1, const Eigen::Vector3d& a0,
                            const Eigen::Vector3d& b0, const Eigen::Vector3d& a1,
                            const Eigen::Vector3d& b1, Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB,
                            double* growth) const;

  /// As SweptCapsuleFromEnds, given also the segment at the midpoint
  /// (s0 + s1) / 2 (am, bm) as SegmentAt computes it: the same bits.
  void SweptCapsuleFromSegments(LinkIndex link, double s0, double s1, const Eigen::Vector3d& a0,
                                const Eigen::Vector3d& b0, const Eigen::Vector3d& a1,
                                const Eigen::Vector3d& b1, const Eigen::Vector3d& am,
                                const Eigen::Vector3d& bm, Eigen::Vector3d* p_WA,
                                Eigen::Vector3d* p_WB, double* growth) const;

  /// The second-order growth over [s0, s1] given `chord`, the larger of the
  /// distances that the link's two segment ends move from s0 to s1:
  /// SweptCapsuleFromSegments's second-order term (the same bits for the
  /// chord it computes). Nondecreasing in chord and in s1 - s0.
  double SecondOrderRadius(LinkIndex link, double chord, double s0, double s1) const;
  /// Upper end of max(|c_0|, |c_1|): the link origin's offset from its motion
  /// parent's origin at both ends (SPEC 3's c, whose interpolation never
  /// leaves that ball); 0 for a link moving on its own. Before CompleteMotion
  /// a slightly larger upper bound (1e-12 relative); for a deferred link not
  /// begun, the same bound from the world positions, max(|p_0 - k_0|, |p_1 -
  /// k_1|) (k the parent's origin: |c| = |R^T (p - k)| = |p - k|).
  double lever(LinkIndex link) const { return links_[link].lever; }
  /// SPEC 3's c at s = 0 (end 0) and s = 1 (end 1) for a link with a motion
  /// parent (its origin in the parent's frame, interpolated linearly
  /// between the two); the world position for a link moving on its own.
  const Eigen::Vector3d& offset(LinkIndex link, int end) const {
    if (!links_[link].begun) CheckLinkBegun(link);
    return end == 0 ? links_[link].p0 : links_[link].p1;
  }
  /// Absolute slack (metres) added for floating-point rounding in SegmentAt.
  double rounding_slack() const { return rounding_slack_; }
  /// Largest absolute coordinate of the poses (world and relative) and link
  /// extent: the magnitude rounding errors of geometry on this motion scale with.
  double coordinate_scale() const { return coordinate_scale_; }

 private:
  struct LinkMotion {
    LinkIndex parent;  // Invalid for the root, or for every link with `independent`.
    // For a link moving on its own: the world frame. For a child with
    // `articulated`: c (position in the parent frame) and r (rotation relative
    // to the parent).
    Eigen::Vector3d p0, p1;
    // q1 already sign-flipped to the shortest arc. Until motion_ready, for a
    // child: the products conj(q_parent) q_link at the two ends, before
    // FinishMotion normalises them.
    Eigen::Quaterniond q0, q1;
    double half_angle = 0;  // Angle between q0 and q1 in R^4.
    // sin(half_angle), its inverse and sin(half_angle / 2): slerp at s = 0,
    // 0.5 and 1 needs no other sine (SlerpPrepared's values, bit for bit).
    double sin_half = 0, inv_sin_half = 0, sin_quarter = 0;
    Eigen::Vector3d a_L, b_L;
    internal::LinkBounds bounds;  // Over the whole pair.
    double extent = 0;            // max(|a|, |b|): farthest segment point from the origin.
    double lever = 0;             // Upper end of max(|p0|, |p1|) for a child, else 0.
    double own_speed = 0;         // Upper end of |p1 - p0|.
    int depth = 1;                // Links from the root to this one, both counted.
    bool ends_ready = true;       // Poses and segments at s = 0, 0.5, 1 composed.
    // Rotations normalised, angle, sines and bounds exact; until then
    // bounds.speed and bounds.angular are upper bounds of the exact ones.
    bool motion_ready = true;
    // Offsets, products, own speed, lever and upper bounds computed (false
    // only for a deferred link until BeginLink).
    bool begun = true;
  };
  // PairGrowthUpper of the link moving by m.
  double GrowthUpper(const LinkMotion& m) const;
  // The rest of a link's motion from its offsets, own speed, lever and
  // rotations (Build's loops, per link): its motion parent's must be done.
  void FinishMotion(LinkMotion* m);
  Eigen::Quaterniond LocalRotation(const LinkMotion& m, double s) const;
  // One composition step of PosesAt and PoseAt: the pose of the link moving
  // by m at s, given its parent's pose (unused for a link on its own).
  LinkPose Compose(const LinkMotion& m, double s, const LinkPose& X_WP) const;
  // PosesAt into num_links() poses at X_WL.
  void PosesAtInto(double s, LinkPose* X_WL) const;

  // Fills every field of links_ (storage may hold an earlier motion's).
  void Build(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, Ends ends,
             const std::vector<char>* deferred);
  // A child's offsets and the products of its relative rotations (Build's
  // first loop, BeginLink).
  void StartChild(LinkMotion* m, const LinkPose& x0, const LinkPose& x1, const LinkPose& k0,
                  const LinkPose& k1) const;
  // kOnDemand: a child's own speed, lever and upper bounds from its parent's
  // (Build's second loop, BeginLink).
  void BoundChild(LinkMotion* m) const;
  void CheckLinkBegun(LinkIndex link) const;
  // The look-ups at s = 0, 0.5 and 1 read composed ends only; bounds and
  // compositions read complete motions only. One test of all_ready_ where
  // everything is (kAll), the link's flag otherwise.
  void CheckEndsReady(LinkIndex link) const {
    if (!all_ready_) CheckLinkEndsReady(link);
  }
  void CheckMotionReady(LinkIndex link) const {
    if (!all_ready_) CheckLinkMotionReady(link);
  }
  void CheckLinkEndsReady(LinkIndex link) const;
  void CheckLinkMotionReady(LinkIndex link) const;

  MotionModel model_;
  std::vector<LinkMotion> links_;
  std::vector<LinkIndex> order_;
  double rounding_slack_ = 0;
  double coordinate_scale_ = 0;
  bool all_ready_ = true;  // Built with kAll: every link's motion and ends done.
  // The poses built from, while a link is deferred (BeginLink reads them).
  const Pose* pose0_ = nullptr;
  const Pose* pose1_ = nullptr;
  // Every link's pose at s = 0 (first n), 0.5 and 1 (PosesAt), so PoseAt at
  // those times is a look-up.
  std::vector<LinkPose> poses_at_ends_;
  // Both models: every link's segment (A, B) at s = 0, 0.5 and 1, in that
  // order, 6 per link: the whole-pair swept capsule of every link reads
  // exactly those.
  std::vector<Eigen::Vector3d> segments_at_ends_;
};

struct PairMotion::Storage {
  std::vector<LinkMotion> links;
  std::vector<LinkIndex> order;
  std::vector<LinkPose> poses;
  std::vector<Eigen::Vector3d> segments;
};

}  // namespace sweptccd
