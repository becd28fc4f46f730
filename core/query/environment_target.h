#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): what a
// link is tested against. Today the one target is the static environment
// (objects of triangles behind BVHs, minus the collision filter). SPEC
// section 8 adds other targets (another avatar's links, a moving object);
// they answer the same questions: which primitives come within a capsule,
// the exact separation at s, whether the link touches at s.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/distance.h"
#include "core/query/ccd_query.h"
#include "core/query/link_capsule.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"

namespace sweptccd::internal {

/// A primitive of the target: an object and a slot of its BVH.
struct Candidate {
  uint32_t object;
  uint32_t slot;
};

/// The static environment seen through a collision filter. Holds references
/// (all three outlive it); const methods are thread-safe.
class EnvironmentTarget {
 public:
  EnvironmentTarget(const Skeleton& skeleton, const Environment& environment,
                    const CollisionFilter& filter)
      : skeleton_(skeleton), env_(environment), filter_(filter) {}

  const Skeleton& skeleton() const { return skeleton_; }
  int num_objects() const { return env_.num_objects(); }
  const TriangleBvh& bvh(ObjectIndex object) const { return env_.object(object).bvh; }
  /// Whether the link is never tested (filtered from every object).
  bool IgnoresAll(LinkIndex link) const { return filter_.IgnoresAll(link); }
  bool Ignores(LinkIndex link, ObjectIndex object) const { return filter_.Ignores(link, object); }

  /// Whether the candidate's triangle comes within the capsule (conservative
  /// towards "inside" by a relative 1e-9 on the cheap tests, exact otherwise).
  bool WithinCapsule(const LinkCapsule& capsule, Candidate candidate) const;
  /// As WithinCapsule (the same answer), for a candidate that a BVH query
  /// with this capsule's segment and radius has just passed: the query has
  /// applied the bounding-sphere refusal already, with wider margins, so it
  /// is not repeated.
  bool WithinCapsuleFromQuery(const LinkCapsule& capsule, Candidate candidate) const;

  /// As CcdEngine::TouchesAt and CcdEngine::Separation (which call these).
  /// TouchesAt also names, in *touching (when given and it touches), the
  /// triangle it found within reach. Separation may start from such a
  /// triangle (`near`): its distance bounds the search from the start, and
  /// at distance 0 (crossing) nothing can be nearer, so the search ends
  /// there. The separation is the same (the least over every triangle);
  /// between triangles at exactly the same distance, `near` is kept.
  bool TouchesAt(const PairMotion& motion, LinkIndex link, double s, double slack,
                 Candidate* touching = nullptr) const;
  bool Separation(const PairMotion& motion, LinkIndex link, double s, double search_radius,
                  ContactRecord* record, const Candidate* near = nullptr) const;

  /// The exact separation of `link` at s over `count` candidates from
  /// `first` only: false when count is 0. Adds count to *triangle_tests.
  bool NearestOf(const PairMotion& motion, LinkIndex link, double s, const Candidate* first,
                 uint32_t count, ContactRecord* best, int64_t* triangle_tests) const;

 private:
  ContactRecord MakeRecord(LinkIndex link, ObjectIndex object, uint32_t slot, double s,
                           const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const SegmentTriangleResult& r, const Eigen::Vector3d& ta,
                           const Eigen::Vector3d& tb, const Eigen::Vector3d& tc) const;

  static bool VertexInsideOrWithin(const LinkCapsule& cap, const Eigen::Vector3d& d, double dd,
                                   double da, const Eigen::Vector3d& ta, const Eigen::Vector3d& tb,
                                   const Eigen::Vector3d& tc);

  const Skeleton& skeleton_;
  const Environment& env_;
  const CollisionFilter& filter_;
};

// Inline: the hottest test of the descent (one call per candidate per interval).
inline bool EnvironmentTarget::WithinCapsule(const LinkCapsule& cap, Candidate c) const {
  Eigen::Vector3d ta, tb, tc;
  env_.object(static_cast<int>(c.object)).bvh.Triangle(c.slot, &ta, &tb, &tc);
  // Cheap answers first: the triangle's bounding sphere around ta misses
  // the capsule (reject), its box misses the capsule's (reject, below), or
  // a vertex is inside it (accept). The sphere and vertex tests compare
  // squared distances with a relative margin of 1e-9 towards "inside".
  const Eigen::Vector3d d = cap.b - cap.a;
  const double dd = d.squaredNorm();
  const double reach = std::sqrt(std::max((tb - ta).squaredNorm(), (tc - ta).squaredNorm()));
  const double da = PointSegmentDistanceSquared(ta, cap.a, d, dd);
  const double far = cap.radius + reach;
  if (da > far * far * (1 + 1e-9)) return false;
  // The triangle's box clear of the capsule's (the segment's box grown by
  // the radius) on some axis, by more than 1e-9 of the magnitudes: every
  // point of it is farther than the radius (the BVH query's leaf test, which
  // refinements from a list do not pass through).
  const Eigen::Vector3d seg_lo = cap.a.cwiseMin(cap.b), seg_hi = cap.a.cwiseMax(cap.b);
  const double grow =
      cap.radius + 1e-9 * (1 + cap.radius +
                           std::max(seg_lo.cwiseAbs().maxCoeff(), seg_hi.cwiseAbs().maxCoeff()));
  if ((ta.cwiseMax(tb).cwiseMax(tc).array() < seg_lo.array() - grow).any() ||
      (ta.cwiseMin(tb).cwiseMin(tc).array() > seg_hi.array() + grow).any()) {
    return false;
  }
  return VertexInsideOrWithin(cap, d, dd, da, ta, tb, tc);
}

inline bool EnvironmentTarget::WithinCapsuleFromQuery(const LinkCapsule& cap, Candidate c) const {
  Eigen::Vector3d ta, tb, tc;
  env_.object(static_cast<int>(c.object)).bvh.Triangle(c.slot, &ta, &tb, &tc);
  const Eigen::Vector3d d = cap.b - cap.a;
  const double dd = d.squaredNorm();
  return VertexInsideOrWithin(cap, d, dd, PointSegmentDistanceSquared(ta, cap.a, d, dd), ta, tb,
                              tc);
}

// WithinCapsule after its sphere refusal: a vertex inside the capsule
// (accept; da is ta's squared distance to the segment), else the exact test.
inline bool EnvironmentTarget::VertexInsideOrWithin(const LinkCapsule& cap,
                                                    const Eigen::Vector3d& d, double dd, double da,
                                                    const Eigen::Vector3d& ta,
                                                    const Eigen::Vector3d& tb,
                                                    const Eigen::Vector3d& tc) {
  if (da <= cap.radius * cap.radius * (1 - 1e-9) ||
      PointSegmentDistanceSquared(tb, cap.a, d, dd) <= cap.radius * cap.radius * (1 - 1e-9) ||
      PointSegmentDistanceSquared(tc, cap.a, d, dd) <= cap.radius * cap.radius * (1 - 1e-9)) {
    return true;
  }
  return SegmentTriangleWithin(cap.a, cap.b, ta, tb, tc, cap.radius);
}

}  // namespace sweptccd::internal
