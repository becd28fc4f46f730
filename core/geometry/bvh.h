#pragma once
// A static bounding volume hierarchy over the triangles of one mesh: binned
// SAH build, 32-byte nodes, triangles stored in leaf order as floats.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/geometry/mesh.h"

namespace sweptccd {

struct Aabb {
  Eigen::Vector3d lo{0, 0, 0};
  Eigen::Vector3d hi{0, 0, 0};
  bool Overlaps(const Aabb& o) const {
    return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
  }
  /// The box that holds nothing: Grow()ing it by a box gives that box.
  static Aabb Empty() {
    return {Eigen::Vector3d::Constant(HUGE_VAL), Eigen::Vector3d::Constant(-HUGE_VAL)};
  }
  /// The box of the capsule of segment [a, b] and radius r.
  static Aabb OfCapsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
    return {a.cwiseMin(b).array() - r, a.cwiseMax(b).array() + r};
  }
  /// Grows this box to hold `o` too.
  void Grow(const Aabb& o) {
    lo = lo.cwiseMin(o.lo);
    hi = hi.cwiseMax(o.hi);
  }
};

/// Immutable after construction; queries are const and thread-safe.
class TriangleBvh {
 public:
  static constexpr int kMaxLeafSize = 4;

  struct Node {
    float lo[3];
    float hi[3];
    uint32_t first;  // Leaf: first slot. Inner: index of the left child (right = first + 1).
    uint32_t count;  // Leaf: number of triangles (>= 1). Inner: 0.
  };

  TriangleBvh() = default;
  /// Builds the hierarchy. The mesh may be discarded afterwards.
  explicit TriangleBvh(const TriangleMesh& mesh);

  size_t num_triangles() const { return ids_.size(); }
  const std::vector<Node>& nodes() const { return nodes_; }
  /// The three vertices of the triangle in leaf slot `slot`.
  void Triangle(uint32_t slot, Eigen::Vector3d* a, Eigen::Vector3d* b, Eigen::Vector3d* c) const {
    const float* t = &tri_[9 * static_cast<size_t>(slot)];
    *a = Eigen::Vector3d(t[0], t[1], t[2]);
    *b = Eigen::Vector3d(t[3], t[4], t[5]);
    *c = Eigen::Vector3d(t[6], t[7], t[8]);
  }
  /// The triangle's id in its mesh (file order after the fan split).
  uint32_t TriangleId(uint32_t slot) const { return ids_[slot]; }
  Aabb NodeBox(uint32_t node) const;
  Aabb bounds() const { return nodes_.empty() ? Aabb{} : NodeBox(0); }
  /// Largest absolute coordinate of any vertex.
  double max_abs_coordinate() const { return max_abs_coordinate_; }
  /// Bytes held by the hierarchy and its triangles.
  size_t memory_bytes() const;

  /// Calls visit(slot) for every triangle whose bounding box meets the box of
  /// the capsule (segment p0-p1, radius) and that lies in a node the capsule
  /// may reach (segment against the node box grown by the radius). A
  /// superset of the triangles within `radius` of the segment; the caller
  /// makes the exact test. Starts at `start_node` (0 = the root).
  template <class Visit>
  void QueryCapsule(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius,
                    Visit&& visit, uint32_t start_node = 0) const;

  /// As QueryCapsule, but `visit(slot)` returns false to stop the traversal
  /// and may lower *radius (branch and bound for nearest-triangle searches);
  /// nodes are tested against the current radius.
  template <class Visit>
  void QueryCapsuleShrinking(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double* radius,
                             Visit&& visit, uint32_t start_node = 0) const;

  /// Segment p0-p1 against box [lo - r, hi + r] by slabs; conservative.
  static bool SegmentMeetsGrownBox(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                   const Eigen::Vector3d& inv_d, const float* lo, const float* hi,
                                   double r);

 private:
  std::vector<Node> nodes_;
  std::vector<float> tri_;     // 9 floats per slot.
  std::vector<uint32_t> ids_;  // Triangle id per slot.
  double max_abs_coordinate_ = 0;
};

inline bool TriangleBvh::SegmentMeetsGrownBox(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                              const Eigen::Vector3d& inv_d, const float* lo,
                                              const float* hi, double r) {
  double tmin = 0, tmax = 1;
  for (int k = 0; k < 3; ++k) {
    const double blo = lo[k] - r, bhi = hi[k] + r;
    if (p0[k] == p1[k]) {
      if (p0[k] < blo || p0[k] > bhi) return false;
      continue;
    }
    double t1 = (blo - p0[k]) * inv_d[k];
    double t2 = (bhi - p0[k]) * inv_d[k];
    if (t1 > t2) std::swap(t1, t2);
    tmin = std::max(tmin, t1);
    tmax = std::min(tmax, t2);
    if (tmin > tmax) return false;
  }
  return true;
}

namespace internal {
inline double Sqr(double x) { return x * x; }
}  // namespace internal

/// Squared distance from q to the segment p0 + t d, t in [0, 1]; dd = |d|^2.
inline double PointSegmentDistanceSquared(const Eigen::Vector3d& q, const Eigen::Vector3d& p0,
                                          const Eigen::Vector3d& d, double dd) {
  double t = dd > 0 ? (q - p0).dot(d) / dd : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (p0 + t * d - q).squaredNorm();
}

template <class Visit>
void TriangleBvh::QueryCapsuleShrinking(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                        double* radius, Visit&& visit,
                                        uint32_t start_node) const {
  if (nodes_.empty()) return;
  const Eigen::Vector3d d = p1 - p0;
  const double dd = d.squaredNorm();
  const Eigen::Vector3d inv_d(1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z());
  // Depth is at most 48 + log2(n) (see the build), so 128 entries suffice.
  uint32_t stack[128];
  int top = 0;
  stack[top++] = start_node;
  while (top > 0) {
    // The slab test rounds; growing the radius by a relative 1e-9 and 1e-9 m
    // keeps it conservative (it only admits more nodes).
    const double r = *radius * (1 + 1e-9) + 1e-9;
    const Node& node = nodes_[stack[--top]];
    if (!SegmentMeetsGrownBox(p0, p1, inv_d, node.lo, node.hi, r)) continue;
    // The slab test admits the corners of the grown box; the bounding sphere
    // of the node rejects many of those (dist(segment, centre) - half diagonal
    // is a lower bound on the distance to anything in the box).
    {
      const Eigen::Vector3d lo(node.lo[0], node.lo[1], node.lo[2]);
      const Eigen::Vector3d hi(node.hi[0], node.hi[1], node.hi[2]);
      const Eigen::Vector3d centre = 0.5 * (lo + hi);
      const double half_diag = 0.5 * (hi - lo).norm();
      if (PointSegmentDistanceSquared(centre, p0, d, dd) >
          internal::Sqr(r + half_diag * (1 + 1e-9))) {
        continue;
      }
    }
    if (node.count == 0) {
      // Nearer child first (popped first): a nearest search then shrinks its
      // radius sooner. Either order visits the same set for a fixed radius.
      const Node& l = nodes_[node.first];
      const Node& rr = nodes_[node.first + 1];
      const Eigen::Vector3d cl(0.5f * (l.lo[0] + l.hi[0]), 0.5f * (l.lo[1] + l.hi[1]),
                               0.5f * (l.lo[2] + l.hi[2]));
      const Eigen::Vector3d cr(0.5f * (rr.lo[0] + rr.hi[0]), 0.5f * (rr.lo[1] + rr.hi[1]),
                               0.5f * (rr.lo[2] + rr.hi[2]));
      const bool left_nearer =
          PointSegmentDistanceSquared(cl, p0, d, dd) <= PointSegmentDistanceSquared(cr, p0, d, dd);
      stack[top++] = left_nearer ? node.first + 1 : node.first;
      stack[top++] = left_nearer ? node.first : node.first + 1;
      continue;
    }
    const Eigen::Vector3d seg_lo = p0.cwiseMin(p1).array() - r;
    const Eigen::Vector3d seg_hi = p0.cwiseMax(p1).array() + r;
    for (uint32_t slot = node.first; slot < node.first + node.count; ++slot) {
      const float* t = &tri_[9 * static_cast<size_t>(slot)];
      bool outside = false;
      for (int k = 0; k < 3 && !outside; ++k) {
        const float tlo = std::min({t[k], t[3 + k], t[6 + k]});
        const float thi = std::max({t[k], t[3 + k], t[6 + k]});
        outside = thi < seg_lo[k] || tlo > seg_hi[k];
      }
      if (outside) continue;
      // Bounding sphere of the triangle around its first vertex.
      const Eigen::Vector3d v0(t[0], t[1], t[2]);
      const double reach = std::sqrt(
          std::max((Eigen::Vector3d(t[3], t[4], t[5]) - v0).squaredNorm(),
                   (Eigen::Vector3d(t[6], t[7], t[8]) - v0).squaredNorm()));
      if (PointSegmentDistanceSquared(v0, p0, d, dd) > internal::Sqr(r + reach * (1 + 1e-9))) {
        continue;
      }
      if (!visit(slot)) return;
    }
  }
}

template <class Visit>
void TriangleBvh::QueryCapsule(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius,
                               Visit&& visit, uint32_t start_node) const {
  double r = radius;
  QueryCapsuleShrinking(
      p0, p1, &r,
      [&](uint32_t slot) {
        visit(slot);
        return true;
      },
      start_node);
}

}  // namespace sweptccd
