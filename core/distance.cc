#include "core/distance.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace sweptccd {

double ClosestPointOnSegment(const Eigen::Vector3d& q, const Eigen::Vector3d& p0,
                             const Eigen::Vector3d& p1, Eigen::Vector3d* closest) {
  const Eigen::Vector3d d = p1 - p0;
  const double dd = d.squaredNorm();
  double t = 0;
  if (dd > 0) t = std::clamp((q - p0).dot(d) / dd, 0.0, 1.0);
  *closest = p0 + t * d;
  return t;
}

// Ericson, Real-Time Collision Detection, 5.1.9, with the degenerate cases.
double SegmentSegmentDistanceSquared(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
                                     const Eigen::Vector3d& p2, const Eigen::Vector3d& q2,
                                     Eigen::Vector3d* c1, Eigen::Vector3d* c2) {
  const Eigen::Vector3d d1 = q1 - p1;
  const Eigen::Vector3d d2 = q2 - p2;
  const Eigen::Vector3d r = p1 - p2;
  const double a = d1.squaredNorm();
  const double e = d2.squaredNorm();
  const double f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 0 && e <= 0) {
    *c1 = p1;
    *c2 = p2;
    return (*c1 - *c2).squaredNorm();
  }
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double denom = a * e - b * b;
      // Non-parallel: closest point of the infinite lines, clamped. Parallel
      // (denom ~ 0): any s works; take 0 and fix up below.
      if (denom > 1e-14 * a * e) {
        s = std::clamp((b * f - c * e) / denom, 0.0, 1.0);
      }
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  *c1 = p1 + d1 * s;
  *c2 = p2 + d2 * t;
  double best = (*c1 - *c2).squaredNorm();
  // Robustness: the clamped solution above is exact in exact arithmetic; with
  // rounding (nearly parallel segments) the endpoint-to-segment distances are
  // a cheap safety net that can only lower the answer towards the true one.
  Eigen::Vector3d q;
  auto consider = [&](const Eigen::Vector3d& x1, const Eigen::Vector3d& x2) {
    const double d = (x1 - x2).squaredNorm();
    if (d < best) {
      best = d;
      *c1 = x1;
      *c2 = x2;
    }
  };
  ClosestPointOnSegment(p1, p2, q2, &q);
  consider(p1, q);
  ClosestPointOnSegment(q1, p2, q2, &q);
  consider(q1, q);
  ClosestPointOnSegment(p2, p1, q1, &q);
  consider(q, p2);
  ClosestPointOnSegment(q2, p1, q1, &q);
  consider(q, q2);
  return best;
}

bool IsDegenerateTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, bc = c - b;
  const double n2 = ab.cross(ac).squaredNorm();
  const double longest2 = std::max({ab.squaredNorm(), ac.squaredNorm(), bc.squaredNorm()});
  // |n| = 2 * area. Relative to the longest edge squared, a ratio below 1e-12
  // means the height is below 1e-12 of the longest edge: a sliver we treat as
  // its edges (the distance error is then at most that height).
  return n2 <= 1e-24 * longest2 * longest2;
}

namespace {

Eigen::Vector3d ClosestPointOnEdges(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  Eigen::Vector3d best, q;
  ClosestPointOnSegment(p, a, b, &best);
  double best_d = (best - p).squaredNorm();
  ClosestPointOnSegment(p, b, c, &q);
  if ((q - p).squaredNorm() < best_d) {
    best = q;
    best_d = (q - p).squaredNorm();
  }
  ClosestPointOnSegment(p, c, a, &q);
  if ((q - p).squaredNorm() < best_d) best = q;
  return best;
}

}  // namespace

// Ericson 5.1.5 (Voronoi regions) for proper triangles.
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  if (IsDegenerateTriangle(a, b, c)) return ClosestPointOnEdges(p, a, b, c);
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double denom = va + vb + vc;
  if (!(denom > 0)) return ClosestPointOnEdges(p, a, b, c);
  const double v = vb / denom, w = vc / denom;
  const Eigen::Vector3d inside = a + ab * v + ac * w;
  // Guard against rounding on slivers: never return a point farther than the
  // best edge point.
  const Eigen::Vector3d edge = ClosestPointOnEdges(p, a, b, c);
  return (inside - p).squaredNorm() <= (edge - p).squaredNorm() ? inside : edge;
}

SegmentTriangleResult SegmentTriangleDistance(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                                              const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                              const Eigen::Vector3d& c) {
  SegmentTriangleResult best;
  double best_d2 = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::Vector3d& on_segment, const Eigen::Vector3d& on_triangle) {
    const double d2 = (on_segment - on_triangle).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best.p_segment = on_segment;
      best.p_triangle = on_triangle;
    }
  };
  const bool degenerate = IsDegenerateTriangle(a, b, c);
  if (!degenerate) {
    // Crossing the plane inside the triangle: distance 0.
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double d0 = n.dot(s0 - a), d1 = n.dot(s1 - a);
    if ((d0 <= 0 && d1 >= 0) || (d0 >= 0 && d1 <= 0)) {
      if (d0 != d1) {
        const double t = d0 / (d0 - d1);
        const Eigen::Vector3d x = s0 + t * (s1 - s0);
        // Barycentric inside test with edge normals (no division).
        const bool inside = n.dot((b - a).cross(x - a)) >= 0 && n.dot((c - b).cross(x - b)) >= 0 &&
                            n.dot((a - c).cross(x - c)) >= 0;
        if (inside) {
          best.distance = 0;
          best.p_segment = x;
          best.p_triangle = x;
          return best;
        }
      }
    }
    // Segment endpoints against the face.
    consider(s0, ClosestPointOnTriangle(s0, a, b, c));
    consider(s1, ClosestPointOnTriangle(s1, a, b, c));
  }
  // Segment against the three edges (for a degenerate triangle, this is all).
  Eigen::Vector3d c1, c2;
  const Eigen::Vector3d* verts[3] = {&a, &b, &c};
  for (int e = 0; e < 3; ++e) {
    SegmentSegmentDistanceSquared(s0, s1, *verts[e], *verts[(e + 1) % 3], &c1, &c2);
    consider(c1, c2);
  }
  best.distance = std::sqrt(best_d2);
  return best;
}

}  // namespace sweptccd
