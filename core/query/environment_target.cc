#include "core/query/environment_target.h"

#include <algorithm>
#include <cmath>

namespace sweptccd::internal {

namespace {

// Unit normal from the triangle towards the link's segment.
Eigen::Vector3d UnitNormal(const SegmentTriangleResult& r, const Eigen::Vector3d& seg_a,
                           const Eigen::Vector3d& seg_b, const Eigen::Vector3d& ta,
                           const Eigen::Vector3d& tb, const Eigen::Vector3d& tc) {
  const Eigen::Vector3d d = r.p_segment - r.p_triangle;
  const double len = d.norm();
  if (len > 1e-12) return d / len;
  // The segment meets the triangle: use the face normal, on the side of the
  // segment's farther end (the link is mostly there).
  Eigen::Vector3d n = (tb - ta).cross(tc - ta);
  if (n.norm() > 0) {
    n.normalize();
    const double da = n.dot(seg_a - r.p_triangle), db = n.dot(seg_b - r.p_triangle);
    return (std::fabs(da) >= std::fabs(db) ? da : db) < 0 ? -n : n;
  }
  // Degenerate triangle crossed by the segment: any direction across the segment.
  Eigen::Vector3d axis = seg_b - seg_a;
  if (axis.norm() == 0) return Eigen::Vector3d(0, 0, 1);
  Eigen::Vector3d perp = axis.cross(Eigen::Vector3d::UnitX());
  if (perp.norm() < 1e-6 * axis.norm()) perp = axis.cross(Eigen::Vector3d::UnitY());
  return perp.normalized();
}

}  // namespace

bool EnvironmentTarget::TouchesAt(const PairMotion& motion, LinkIndex link, double s, double slack,
                                  Candidate* touching) const {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion.SegmentAt(link, s, &a, &b);
  const double reach = skeleton_.link(link).radius + std::max(0.0, slack);
  bool touches = false;
  for (ObjectIndex o(0); o < env_.num_objects() && !touches; ++o) {
    if (filter_.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env_.object(o).bvh;
    double search = reach;
    bvh.QueryCapsuleShrinking(a, b, &search, [&](uint32_t slot) {
      bvh.Triangle(slot, &ta, &tb, &tc);
      touches = SegmentTriangleWithin(a, b, ta, tb, tc, reach);  // The distance's answer.
      if (touches && touching != nullptr) {
        *touching = Candidate{static_cast<uint32_t>(o.value()), slot};
      }
      return !touches;
    });
  }
  return touches;
}

bool EnvironmentTarget::Separation(const PairMotion& motion, LinkIndex link, double s,
                                   double search_radius, ContactRecord* record,
                                   const Candidate* near) const {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion.SegmentAt(link, s, &a, &b);
  const double radius = skeleton_.link(link).radius;
  const double reach = radius + std::max(0.0, search_radius);
  bool found = false;
  double nearest = reach;  // The least distance found so far (when found).
  if (near != nullptr && near->object < static_cast<uint32_t>(env_.num_objects()) &&
      near->slot < env_.object(static_cast<int>(near->object)).bvh.num_triangles()) {
    const ObjectIndex o(static_cast<int>(near->object));
    if (!filter_.Ignores(link, o)) {
      const TriangleBvh& bvh = env_.object(o).bvh;
      bvh.Triangle(near->slot, &ta, &tb, &tc);
      const SegmentTriangleResult r = SegmentTriangleDistance(a, b, ta, tb, tc);
      if (r.distance <= reach) {
        found = true;
        nearest = r.distance;
        *record = MakeRecord(link, o, near->slot, s, a, b, r, ta, tb, tc);
        if (r.distance == 0) return true;  // Nothing is nearer than a crossing triangle.
      }
    }
  }
  for (ObjectIndex o(0); o < env_.num_objects(); ++o) {
    if (filter_.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env_.object(o).bvh;
    // Branch and bound: the search radius shrinks to the best distance so far.
    double search = nearest;
    bvh.QueryCapsuleShrinking(a, b, &search, [&](uint32_t slot) {
      bvh.Triangle(slot, &ta, &tb, &tc);
      // Most triangles the search visits are farther than the best so far;
      // the cheap refusals of SegmentTriangleWithin skip them before the
      // closest points are measured.
      if (!SegmentTriangleWithin(a, b, ta, tb, tc, search)) return true;
      const SegmentTriangleResult r = SegmentTriangleDistance(a, b, ta, tb, tc);
      if (r.distance > reach) return true;
      search = std::min(search, r.distance);
      const double sep = r.distance - radius;
      if (!found || sep < record->separation) {
        found = true;
        nearest = std::min(nearest, r.distance);
        *record = MakeRecord(link, o, slot, s, a, b, r, ta, tb, tc);
      }
      return r.distance > 0;  // Nothing is nearer than a crossing triangle.
    });
  }
  return found;
}

bool EnvironmentTarget::NearestOf(const PairMotion& motion, LinkIndex link, double s,
                                  const Candidate* first, uint32_t count, ContactRecord* best,
                                  int64_t* triangle_tests) const {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion.SegmentAt(link, s, &a, &b);
  const double radius = skeleton_.link(link).radius;
  bool found = false;
  for (uint32_t k = 0; k < count; ++k) {
    const ObjectIndex object(static_cast<int>(first[k].object));
    env_.object(object).bvh.Triangle(first[k].slot, &ta, &tb, &tc);
    ++*triangle_tests;
    const SegmentTriangleResult r = SegmentTriangleDistance(a, b, ta, tb, tc);
    const double sep = r.distance - radius;
    if (!found || sep < best->separation) {
      found = true;
      *best = MakeRecord(link, object, first[k].slot, s, a, b, r, ta, tb, tc);
    }
  }
  return found;
}

ContactRecord EnvironmentTarget::MakeRecord(LinkIndex link, ObjectIndex object, uint32_t slot,
                                            double s, const Eigen::Vector3d& a,
                                            const Eigen::Vector3d& b,
                                            const SegmentTriangleResult& r,
                                            const Eigen::Vector3d& ta, const Eigen::Vector3d& tb,
                                            const Eigen::Vector3d& tc) const {
  ContactRecord record;
  record.link = link;
  record.object = object;
  record.triangle = env_.object(object).bvh.TriangleId(slot);
  record.s = s;
  record.point_link = r.p_segment;
  record.point_env = r.p_triangle;
  record.normal = UnitNormal(r, a, b, ta, tb, tc);
  record.separation = r.distance - skeleton_.link(link).radius;
  return record;
}

}  // namespace sweptccd::internal
