#pragma once
// The first time of contact between one avatar pair and another entity of a
// shared world (SPEC section 8): link against link of another avatar, or link
// against a tracked object's triangles, over the window where both exist,
// with the certificate of SPEC 6 (G1-G3) restricted to the two entities.
//
// Time runs as tau, microseconds since the avatar pair's utime0 (exact for
// the integer utimes of every sample). The window is split at the other
// entity's sample times into pieces, each with one motion of the other
// entity. The descent is chronological over (link, time interval) items,
// as core/query's: an item is free when the swept bounds (segment at the
// interval's midpoint grown by PairMotion's certified growth) cannot meet;
// a narrow item (width <= eps) closes when a sample time is within delta.
// Runs on the CPU only (every backend gives the same answers).

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/motion_memo.h"
#include "core/geometry/bvh.h"
#include "core/world/world.h"

namespace sweptccd::world {

struct EntityQueryOptions {
  double eps_s = 1e-4;    // Bracket width, seconds (> 0).
  double delta_m = 1e-3;  // Distance tolerance of G3, metres (> 0).
  bool per_link = false;  // A bracket for every link of A that touches E.
  /// Work limit: items visited per (pair, entity). Past it: `undecided`.
  int64_t max_intervals = 2'000'000;
};

/// One witness between A and E, world frame.
struct OtherContact {
  int link = 0;           // A's link.
  int other_link = -1;    // E's link (avatar), else -1.
  int64_t triangle = -1;  // E's triangle id (object), else -1.
  double tau = 0;         // Microseconds since utime0.
  Eigen::Vector3d point_link{0, 0, 0}, point_other{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};  // Unit, from E's point towards A's.
  double separation = 0;
};

/// A bracket in tau (per link, or the answer's own).
struct OtherBracket {
  int link = -1;
  double tau_lo = 0, tau_hi = 0;
  bool initially_colliding = false;
  bool undecided = false;
  bool has_witness = false;
  OtherContact witness;
};

/// A bracket as `sweptccd world` prints it and the daemon publishes it: s
/// rounded so that it never narrows the certified bracket (s_lo down, s_hi
/// up), t inside the window [t_from, t_to] (its ends are exact integers).
struct PrintedBracket {
  double s_lo = 0, s_hi = 0, t_lo = 0, t_hi = 0;
};
PrintedBracket PrintBracket(const OtherBracket& b, int64_t utime0, int64_t utime1, int64_t t_from,
                            int64_t t_to);

struct OtherAnswer {
  bool contact = false;
  OtherBracket bracket;             // When contact: the earliest bracket.
  std::vector<OtherBracket> links;  // Per-link mode: by link index.
  int64_t intervals = 0;            // Items visited.
  bool culled_by_box = false;       // The entity-level broad phase cleared it.
};

/// One piece of the window: [tau0, tau1] in which E moves with one motion,
/// that of its samples k and k+1 (k+1 == k for an entity with one sample).
struct Piece {
  double tau0 = 0, tau1 = 0;
  int k = 0;
  double e_tau0 = 0;            // Sample k's time in tau.
  double e_dur = 0;             // Microseconds from sample k to k+1 (0: static).
  double SE(double tau) const;  // E's normalised time at tau, in [0, 1].
};

/// Splits the window [t_from, t_to] (utimes, t_from <= t_to, inside both
/// the pair and [first, last] of `samples`) at the sample times.
std::vector<Piece> SplitWindow(int64_t utime0, int64_t t_from, int64_t t_to,
                               const std::vector<int64_t>& samples);

/// What A's links are tested against over the pieces. Implementations:
/// another avatar (candidates: its links) or a tracked object (one
/// candidate: the object; triangles come from its BVH).
class OtherTarget {
 public:
  virtual ~OtherTarget() = default;
  /// Unfiltered candidates of A's link at the start, into *out (replaced;
  /// its capacity reused).
  virtual void RootCandidatesInto(int link_a, std::vector<int>* out) const = 0;
  /// The same, returned.
  std::vector<int> RootCandidates(int link_a) const {
    std::vector<int> out;
    RootCandidatesInto(link_a, &out);
    return out;
  }
  /// A box holding E over the piece (the entity-level broad phase).
  virtual Aabb PieceBox(const Piece& piece, double tau0, double tau1) const = 0;
  /// box.Overlaps(PieceBox(piece, tau0, tau1)), which a target may answer
  /// without the whole PieceBox (a union of boxes that overlaps `box` still
  /// does when it grows).
  virtual bool PieceBoxMeets(const Piece& piece, double tau0, double tau1, const Aabb& box) const {
    return box.Overlaps(PieceBox(piece, tau0, tau1));
  }
  /// Removes from *cands those that cannot come within A's link over
  /// [tau0, tau1]: A's swept capsule is its segment (a, b) at the interval's
  /// midpoint, every point within `growth_a` of its midpoint position,
  /// link radius `radius_a`; `tol` is the rounding slack.
  virtual void Cull(const Piece& piece, double tau0, double tau1, const Eigen::Vector3d& a,
                    const Eigen::Vector3d& b, double radius_a, double growth_a,
                    std::vector<int>* cands) const = 0;
  /// The nearest candidate to A's link segment (a, b) at tau, within
  /// `search` of its capsule surface; false when none.
  virtual bool Nearest(const Piece& piece, double tau, int link_a, const Eigen::Vector3d& a,
                       const Eigen::Vector3d& b, double radius_a, const std::vector<int>& cands,
                       double search, OtherContact* out) const = 0;
  /// Rounding slack (metres) of this target's geometry.
  virtual double tolerance() const = 0;
  /// The link-level broad phase: per candidate (by index), a box holding
  /// every box that Cull and Nearest test that candidate with over any part
  /// of the piece's sample interval (LinkSweepBoxes with extra 0). False,
  /// *boxes untouched, when the target has none (then every candidate is
  /// kept).
  virtual bool LinkBoxes(const Piece& piece, std::vector<Aabb>* boxes) const {
    (void)piece;
    (void)boxes;
    return false;
  }
};

/// Largest absolute coordinate of an entity's samples and geometry (its
/// rounding slack scales with it); O(samples).
double EntityScale(const AvatarEntity& entity);
double EntityScale(const ObjectEntity& entity);

/// The same over the geometry and only the samples the window's pieces use
/// (pieces.front().k to pieces.back().k + 1, clamped to the samples): the
/// scale a window's answer is computed with. It depends on nothing outside
/// the window, so a live service holding only those samples (a slice of
/// the entity's history, re-based so that its first sample is
/// pieces.front().k) answers bit-equal to `sweptccd world`. O(pieces).
/// Precondition: pieces non-empty and from SplitWindow over entity.used.
double WindowScale(const AvatarEntity& entity, const std::vector<Piece>& pieces);
double WindowScale(const ObjectEntity& entity, const std::vector<Piece>& pieces);

/// An avatar's motions over its sample intervals with their memos (its
/// links' poses at the times asked), kept across answers: every pair of
/// every other avatar whose window meets interval k asks for the same
/// motion. At most `max_kept` intervals are kept (the farthest goes), each
/// memo with at most 64 times (callers visit intervals in time order). Not
/// thread-safe; must outlive the targets made with it.
class IntervalMotions {
 public:
  /// `link_boxes`, when not empty, holds LinkSweepBoxes(skeleton, motion
  /// of interval k, 0) for every interval k, made by the caller (who built
  /// each motion once already); LinkBoxesOf then answers from it without
  /// building the motion.
  explicit IntervalMotions(const AvatarEntity& entity, size_t max_kept = 4,
                           std::vector<std::vector<Aabb>> link_boxes = {});
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

 private:
  struct Held {
    PairMotion motion;
    MotionMemo memo;  // Over `motion`.
    std::vector<Aabb> link_boxes;  // LinkSweepBoxes of `motion`; empty: not yet.
    Held(const AvatarEntity& e, int k, int k1);
  };
  const AvatarEntity& entity_;
  size_t max_kept_;
  std::map<int, std::unique_ptr<Held>> held_;
  std::vector<std::vector<Aabb>> given_link_boxes_;  // By interval; empty: none given.
};

/// The other entity's targets; `scale` is EntityScale of it (< 0: computed
/// here, O(samples); callers answering many pairs compute it once). An
/// avatar target takes B's motions from `motions` when given (B's), else
/// keeps its own.
std::unique_ptr<OtherTarget> MakeAvatarTarget(const World& world, int a, int b, double scale = -1,
                                              IntervalMotions* motions = nullptr);
std::unique_ptr<OtherTarget> MakeObjectTarget(const World& world, int a, int o, double scale = -1);

/// The broad phase over entities. A box holds the certified swept capsule of
/// every link (or every mesh point) over one motion, padded far above the
/// rounding of the box itself; boxes apart mean the entities do not touch
/// over that motion, and then the answer is `free` with no link work. (The
/// descent could instead accept a near miss within delta, which G3 allows
/// too: `sweptccd world` and the daemon both apply these boxes, so they
/// agree.) Each box depends on its own motion's samples only, so a live
/// service holding those samples computes the same bits as `sweptccd world`.
///
/// Every link of an avatar over `motion` (one pair or one sample interval).
Aabb AvatarMotionBox(const Skeleton& skeleton, const PairMotion& motion);
/// The largest distance from an object's frame origin to a point of its mesh
/// (of its BVH's bounds), rounded up.
double ObjectRadius(const TriangleBvh& bvh);
/// A tracked object moving from x0 to x1 (x1 == x0 for an object with one
/// sample): its frame origin moves on the segment, every mesh point within
/// `radius` (ObjectRadius) of it; `mesh_scale` is the BVH's largest absolute
/// coordinate.
Aabb ObjectMotionBox(const RigidSample& x0, const RigidSample& x1, double radius,
                     double mesh_scale);

/// Answers A's pair (poses pose0, pose1 under `motion_a`) against `target`
/// over `pieces` (chronological, contiguous, non-empty). Deterministic.
OtherAnswer AnswerOther(const Skeleton& skeleton_a, const PairMotion& motion_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options);
/// The same with A's memo, which callers answering one pair against many
/// entities keep across them (the same bits: the memo answers as the motion),
/// and optionally A's LinkSweepBoxes(skeleton_a, memo_a->motion(), 0), which
/// they compute once for all entities (else computed here).
OtherAnswer AnswerOther(const Skeleton& skeleton_a, MotionMemo* memo_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options,
                        const std::vector<Aabb>* link_boxes_a = nullptr);

}  // namespace sweptccd::world
