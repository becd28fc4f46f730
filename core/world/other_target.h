#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): what A's links
// are tested against over the window's pieces - the counterpart of
// core/query's EnvironmentTarget. Implementations: another avatar
// (avatar_target.h; candidates: its links) or a tracked object
// (object_target.h; one candidate, the object; triangles from its BVH).

#include <Eigen/Core>
#include <vector>

#include "core/geometry/bvh.h"
#include "core/world/entity_query.h"
#include "core/world/window_split.h"

namespace sweptccd::world {

class OtherTarget {
 public:
  virtual ~OtherTarget() = default;
  /// Unfiltered candidates of A's link at the start, into *out (replaced;
  /// its capacity reused).
  virtual void RootCandidatesInto(LinkIndex link_a, std::vector<int>* out) const = 0;
  /// The same, returned.
  std::vector<int> RootCandidates(LinkIndex link_a) const {
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
  /// link radius `radius_a`.
  virtual void Cull(const Piece& piece, double tau0, double tau1, const Eigen::Vector3d& a,
                    const Eigen::Vector3d& b, double radius_a, double growth_a,
                    std::vector<int>* cands) const = 0;
  /// The nearest candidate to A's link segment (a, b) at tau, within
  /// `search` of its capsule surface; false when none.
  virtual bool Nearest(const Piece& piece, double tau, LinkIndex link_a, const Eigen::Vector3d& a,
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
  /// Per candidate, its near box over the piece's sample interval with
  /// `margin` (near_link_boxes.h: NearLinkBoxes for an avatar's links, the
  /// entity box grown by the margin for an object). False, *boxes
  /// untouched, when the target has none.
  virtual bool NearLinkBoxes(const Piece& piece, double margin, std::vector<Aabb>* boxes) const {
    (void)piece;
    (void)margin;
    (void)boxes;
    return false;
  }
};

/// Widens a normalised time range by a relative 1e-12 (the rounding of the
/// tau -> s mapping), clamped to [0, 1]. Every box and capsule over a piece
/// is taken over the widened range.
inline void WidenS(double* s0, double* s1) {
  *s0 = std::max(0.0, *s0 - 1e-12);
  *s1 = std::min(1.0, *s1 + 1e-12);
}

/// v / |v|, or `fallback` when v is 0.
inline Eigen::Vector3d UnitOr(const Eigen::Vector3d& v, const Eigen::Vector3d& fallback) {
  const double n = v.norm();
  return n > 0 ? Eigen::Vector3d(v / n) : fallback;
}

}  // namespace sweptccd::world
