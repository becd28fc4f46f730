#include "core/geometry/distance.h"

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

namespace {

// Nearly parallel segments (under ~0.01 rad): the closed form loses up to
// eps / angle^2 and alternating projections converge too slowly. The squared
// distance from P1(s) to the other segment is convex in s: golden-section
// search over s, each step a well-conditioned projection. Lowers *best (and
// the closest points) when it finds a closer pair.
void NearlyParallelSearch(const Eigen::Vector3d& p1, const Eigen::Vector3d& d1,
                          const Eigen::Vector3d& p2, const Eigen::Vector3d& q2, double* best,
                          Eigen::Vector3d* c1, Eigen::Vector3d* c2) {
  auto f = [&](double u, Eigen::Vector3d* x1, Eigen::Vector3d* x2) {
    *x1 = p1 + d1 * u;
    ClosestPointOnSegment(*x1, p2, q2, x2);
    return (*x1 - *x2).squaredNorm();
  };
  constexpr double kGolden = 0.6180339887498949;
  double lo = 0, hi = 1;
  Eigen::Vector3d x1, x2;
  double m1 = hi - kGolden * (hi - lo), m2 = lo + kGolden * (hi - lo);
  double f1 = f(m1, &x1, &x2), f2 = f(m2, &x1, &x2);
  for (int it = 0; it < 80 && hi - lo > 1e-15; ++it) {
    if (f1 <= f2) {
      hi = m2;
      m2 = m1;
      f2 = f1;
      m1 = hi - kGolden * (hi - lo);
      f1 = f(m1, &x1, &x2);
    } else {
      lo = m1;
      m1 = m2;
      f1 = f2;
      m2 = lo + kGolden * (hi - lo);
      f2 = f(m2, &x1, &x2);
    }
  }
  const double d = f(0.5 * (lo + hi), &x1, &x2);
  if (d < *best) {
    *best = d;
    *c1 = x1;
    *c2 = x2;
  }
}

}  // namespace

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
  // Near-parallel segments make the closed form ill-conditioned. Alternating
  // projections (closest point on one segment to a point of the other) are
  // each well-conditioned and never increase the distance; two rounds recover
  // the lost digits.
  for (int round = 0; round < 2; ++round) {
    if (e > 0) t = std::clamp((*c1 - p2).dot(d2) / e, 0.0, 1.0);
    *c2 = p2 + d2 * t;
    if (a > 0) s = std::clamp((*c2 - p1).dot(d1) / a, 0.0, 1.0);
    const Eigen::Vector3d next = p1 + d1 * s;
    if ((next - *c2).squaredNorm() <= (*c1 - *c2).squaredNorm()) *c1 = next;
  }
  double best = (*c1 - *c2).squaredNorm();
  if (a > 0 && e > 0) {
    const double b = d1.dot(d2);
    if (a * e - b * b <= 1e-4 * a * e) {
      NearlyParallelSearch(p1, d1, p2, q2, &best, c1, c2);
    }
  }
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

namespace {

// Twice the area squared (|ab x ac|^2) and the longest edge squared.
struct TriangleShape {
  double n2 = 0, longest2 = 0;
  // Height / longest edge > sqrt(f) (n2 = (longest edge * height)^2).
  bool HeightAbove(double f) const { return n2 > f * longest2 * longest2; }
};

TriangleShape ShapeOf(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                      const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, bc = c - b;
  return {ab.cross(ac).squaredNorm(),
          std::max({ab.squaredNorm(), ac.squaredNorm(), bc.squaredNorm()})};
}

}  // namespace

bool IsDegenerateTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c) {
  // |n| = 2 * area = longest edge * height. A height below 1e-8 of the
  // longest edge makes a sliver we treat as its edges: the distance is then
  // off by at most that height, while the plane of a thinner sliver is only
  // known to ~1e-16 * L / h radians, which misplaces the projection by more.
  return !ShapeOf(a, b, c).HeightAbove(1e-16);
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

namespace {

// The unit normal of a proper triangle from the two edges at the vertex
// opposite the longest edge: the cross product of the two shortest edges has
// relative error ~ eps * L / h for a sliver of length L and height h, where
// barycentric formulas lose ~ eps * (L / h)^2. The orientation is that of
// (b - a) x (c - a).
Eigen::Vector3d StableUnitNormal(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  const double ab = (b - a).squaredNorm(), bc = (c - b).squaredNorm(), ca = (a - c).squaredNorm();
  Eigen::Vector3d n;
  if (bc >= ab && bc >= ca) {
    n = (b - a).cross(c - a);  // Longest edge bc: vertex a.
  } else if (ca >= ab) {
    n = (c - b).cross(a - b);  // Longest edge ca: vertex b.
  } else {
    n = (a - c).cross(b - c);  // Longest edge ab: vertex c.
  }
  return n.normalized();
}

// Whether q (on the triangle's plane, up to rounding) is inside the triangle.
bool InsideTriangle(const Eigen::Vector3d& q, const Eigen::Vector3d& n, const Eigen::Vector3d& a,
                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return n.dot((b - a).cross(q - a)) >= 0 && n.dot((c - b).cross(q - b)) >= 0 &&
         n.dot((a - c).cross(q - c)) >= 0;
}

// p projected onto the plane of the proper triangle (a, b, c) with unit
// normal n, measured from the vertex nearest p (smaller differences, smaller
// rounding).
Eigen::Vector3d ProjectOntoPlane(const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                                 const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  const Eigen::Vector3d& base = (p - a).squaredNorm() <= (p - b).squaredNorm()
                                    ? ((p - a).squaredNorm() <= (p - c).squaredNorm() ? a : c)
                                    : ((p - b).squaredNorm() <= (p - c).squaredNorm() ? b : c);
  return p - n * n.dot(p - base);
}

}  // namespace

namespace {

// ClosestPointOnTriangle for a proper triangle whose StableUnitNormal is n.
Eigen::Vector3d ClosestPointOnProperTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                                             const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                             const Eigen::Vector3d& c) {
  // Project onto the plane; inside: that is the closest point. Outside: the
  // closest point is on the boundary (edges are well-conditioned).
  const Eigen::Vector3d q = ProjectOntoPlane(p, n, a, b, c);
  const Eigen::Vector3d edge = ClosestPointOnEdges(p, a, b, c);
  if (InsideTriangle(q, n, a, b, c) && (q - p).squaredNorm() <= (edge - p).squaredNorm()) {
    return q;
  }
  return edge;
}

}  // namespace

Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  if (IsDegenerateTriangle(a, b, c)) return ClosestPointOnEdges(p, a, b, c);
  return ClosestPointOnProperTriangle(p, StableUnitNormal(a, b, c), a, b, c);
}

namespace {

// The radius plus the early refusals' margin: 1e-9 of the magnitudes (the
// radius, the longest edge, the segment's ends measured from a).
double RefusalDistance(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                       const Eigen::Vector3d& a, double radius, double longest2) {
  const double scale = radius + std::sqrt(longest2) +
                       std::max((s0 - a).cwiseAbs().maxCoeff(), (s1 - a).cwiseAbs().maxCoeff());
  return radius + 1e-9 * scale;
}

// Whether the segment's projection onto the unit axis u and the
// triangle's (its three vertices) lie more than `apart` apart. Everything
// is measured from a.
bool ApartAlong(const Eigen::Vector3d& u, const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                double apart) {
  const double s_at = u.dot(s0 - a), s_to = u.dot(s1 - a);
  const double pb = u.dot(b - a), pc = u.dot(c - a);
  return std::min(s_at, s_to) - std::max({0.0, pb, pc}) > apart ||
         std::min({0.0, pb, pc}) - std::max(s_at, s_to) > apart;
}

// Whether the segment lies beyond one edge of the triangle, in its plane,
// by more than radius: both ends farther than radius + margin out along the
// edge's outward normal within the plane (e x n, unit). The triangle lies on
// the inner side of that line, so every point of the segment is farther than
// radius from every point of the triangle. For a triangle at least 1e-3 as
// high as long, n, and so each edge normal, is known to ~1e-13 radians; the
// margin (1e-9 of the magnitudes, as the plane refusal's) is far above that
// and above the rounding of the full distance. `beyond`: radius plus that
// margin (RefusalDistance).
bool BeyondAnEdge(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& n,
                  const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  double beyond) {
  const Eigen::Vector3d* v[3] = {&a, &b, &c};
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector3d& p = *v[e];
    const Eigen::Vector3d out = (*v[(e + 1) % 3] - p).cross(n).normalized();
    if (out.dot(s0 - p) > beyond && out.dot(s1 - p) > beyond) return true;
  }
  return false;
}

// v / |v| to within a few ulps of unit length, for any finite nonzero v.
// A norm taken from a subnormal (or overflowing) square is off by up to
// 22 % (or infinite), and an axis divided by it would be as much too long,
// its gaps too; such a v is first divided by its largest magnitude. A
// square of at least 1e-290 holds every component's square to better than
// 1e-17 of itself. False for a zero, infinite or NaN v.
bool UnitAxis(const Eigen::Vector3d& v, Eigen::Vector3d* unit) {
  const double square = v.squaredNorm();
  if (square >= 1e-290 && square <= 1e290) {
    *unit = v * (1.0 / std::sqrt(square));
    return true;
  }
  const double largest = v.cwiseAbs().maxCoeff();
  if (!(largest > 0) || !std::isfinite(largest)) return false;
  const Eigen::Vector3d w = v / largest;  // Largest component +-1.
  *unit = w * (1.0 / w.norm());
  return true;
}

// Whether the segment and the triangle are apart by more than radius along
// the axis across the segment and one edge (the unit vector of d x e). Both
// project onto it as intervals (the segment's nearly a point). Any unit
// axis gives a lower bound on the distance, so the rounding of the axis's
// direction only turns it (still an axis; the segment's two ends are both
// projected, so a turned axis is not assumed across it), and UnitAxis keeps
// its length to a few ulps; `apart` is RefusalDistance. It decides where
// the segment passes an edge, whose nearest points neither the plane nor
// the edge normals separate.
bool ApartAcrossAnEdge(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                       const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       double apart) {
  const Eigen::Vector3d d = s1 - s0;
  const Eigen::Vector3d e[3] = {b - a, c - b, a - c};
  for (const Eigen::Vector3d& edge : e) {
    Eigen::Vector3d m;
    if (!UnitAxis(d.cross(edge), &m)) continue;  // Parallel (or a point): no axis.
    if (ApartAlong(m, s0, s1, a, b, c, apart)) return true;
  }
  return false;
}

// Whether the segment and the triangle are apart by more than radius along
// the axis from the vertex nearest the segment to its nearest point there.
// Where the least distance is from a vertex (to an end or to the segment's
// inside), that is its direction and the test is decisive. Any unit axis
// bounds the distance from below; all five points are projected, so the
// rounding of the axis's direction does not matter, and UnitAxis keeps its
// length to a few ulps; `apart` is RefusalDistance.
bool ApartFromNearestVertex(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                            const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c, double apart) {
  double nearest = HUGE_VAL;
  Eigen::Vector3d axis(0, 0, 0), on_segment;
  for (const Eigen::Vector3d* v : {&a, &b, &c}) {
    ClosestPointOnSegment(*v, s0, s1, &on_segment);
    const Eigen::Vector3d w = *v - on_segment;
    if (w.squaredNorm() < nearest) {
      nearest = w.squaredNorm();
      axis = w;
    }
  }
  return UnitAxis(axis, &axis) && ApartAlong(axis, s0, s1, a, b, c, apart);
}

}  // namespace

namespace {

// SegmentTriangleSteps' end tests with a radius, for a proper triangle with
// StableUnitNormal n: whether an end of the segment is within radius of the
// triangle (its face or its edges). Stops at the first that is.
bool EndsWithin(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1, const Eigen::Vector3d& n,
                const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                double radius) {
  // The ends' projections, kept for their face tests below (the same
  // bits as ClosestPointOnProperTriangle's).
  Eigen::Vector3d q[2];
  bool inside[2];
  const Eigen::Vector3d* ends[2] = {&s0, &s1};
  for (int k = 0; k < 2; ++k) {
    q[k] = ProjectOntoPlane(*ends[k], n, a, b, c);
    inside[k] = InsideTriangle(q[k], n, a, b, c);
    if (inside[k] && std::sqrt((*ends[k] - q[k]).squaredNorm()) <= radius) return true;
  }
  // Only whether the least distance is at most radius matters: the
  // square root is nondecreasing, so it is, exactly when one of the
  // distances considered is. Stop at the first.
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d& p = *ends[k];
    const Eigen::Vector3d edge = ClosestPointOnEdges(p, a, b, c);
    const Eigen::Vector3d& face =
        inside[k] && (q[k] - p).squaredNorm() <= (edge - p).squaredNorm() ? q[k] : edge;
    if (std::sqrt((p - face).squaredNorm()) <= radius) return true;
  }
  return false;
}

// SegmentTriangleDistance's steps. With `radius` (not null) only *within
// matters: whether the distance is at most *radius. It may then be decided
// early, where an answer implies the full one, and the result is not filled:
// - both ends on one side of the plane, farther than radius: so is every
//   point of the segment, and the triangle lies in the plane. The margin
//   (1e-9 of the magnitudes) is far above the rounding of these plane
//   distances and of the full distance, for a triangle whose height is at
//   least 1e-3 of its longest edge (its normal is then known to ~1e-13
//   radians); thinner ones go on;
// - both ends beyond one edge, in the plane, farther than radius
//   (BeyondAnEdge), or the segment and the triangle apart along the axis
//   across the segment and an edge (ApartAcrossAnEdge) or along the axis
//   from the vertex nearest the segment (ApartFromNearestVertex); the plane
//   refusal's margin and triangles. A refusal means the distance exceeds
//   radius by more than any rounding, so it cannot meet an acceptance
//   below and the order of the two does not matter;
// - an end whose projection lies inside the triangle, within radius: the
//   full steps consider that end against its closest point on the
//   triangle (ClosestPointOnTriangle: this projection, by the same
//   arithmetic, or an edge point nearer still), so their distance is at
//   most this one;
// - otherwise the full steps, stopping at the first distance within
//   radius (the least is within exactly when one is).
SegmentTriangleResult SegmentTriangleSteps(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                                           const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                           const Eigen::Vector3d& c, const double* radius,
                                           bool* within) {
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
  const TriangleShape shape = ShapeOf(a, b, c);
  if (shape.HeightAbove(1e-16)) {  // Not IsDegenerateTriangle.
    const Eigen::Vector3d n = StableUnitNormal(a, b, c);
    const double d0 = n.dot(s0 - a), d1 = n.dot(s1 - a);
    // The early refusals' triangles and distance (radius plus margin).
    const bool refusals = radius != nullptr && shape.HeightAbove(1e-6);
    const double apart = refusals ? RefusalDistance(s0, s1, a, *radius, shape.longest2) : 0.0;
    if (refusals && (d0 > 0) == (d1 > 0)) {
      if (std::min(std::abs(d0), std::abs(d1)) > apart) {
        *within = false;
        return best;
      }
    }
    // Crossing the plane inside the triangle: distance 0.
    if ((d0 <= 0 && d1 >= 0) || (d0 >= 0 && d1 <= 0)) {
      if (d0 != d1) {
        const double t = d0 / (d0 - d1);
        const Eigen::Vector3d x = s0 + t * (s1 - s0);
        if (InsideTriangle(x, n, a, b, c)) {
          // They intersect: distance 0. The triangle's point is put exactly
          // on its plane (x may be off it by rounding, ~1e-16 of the scale);
          // the segment's point stays on the segment.
          best.distance = 0;
          best.p_segment = x;
          best.p_triangle = x - n * n.dot(x - a);
          if (radius != nullptr) *within = true;
          return best;
        }
      }
    }
    if (radius != nullptr) {
      // Refusals, each only where the distance exceeds radius by more than
      // the margin, so none can change what the steps below decide.
      if (refusals &&
          (BeyondAnEdge(s0, s1, n, a, b, c, apart) || ApartAcrossAnEdge(s0, s1, a, b, c, apart) ||
           ApartFromNearestVertex(s0, s1, a, b, c, apart))) {
        *within = false;
        return best;
      }
      if (EndsWithin(s0, s1, n, a, b, c, *radius)) {
        *within = true;
        return best;
      }
    } else {
      // Segment endpoints against the face (ClosestPointOnTriangle: the
      // triangle is proper and n its StableUnitNormal).
      consider(s0, ClosestPointOnProperTriangle(s0, n, a, b, c));
      consider(s1, ClosestPointOnProperTriangle(s1, n, a, b, c));
    }
  }
  // Segment against the three edges (for a degenerate triangle, this is all).
  Eigen::Vector3d c1, c2;
  const Eigen::Vector3d* verts[3] = {&a, &b, &c};
  for (int e = 0; e < 3; ++e) {
    SegmentSegmentDistanceSquared(s0, s1, *verts[e], *verts[(e + 1) % 3], &c1, &c2);
    consider(c1, c2);
    if (radius != nullptr && std::sqrt(best_d2) <= *radius) {  // As above: the first suffices.
      *within = true;
      return best;
    }
  }
  best.distance = std::sqrt(best_d2);
  if (radius != nullptr) *within = best.distance <= *radius;
  return best;
}

}  // namespace

SegmentTriangleResult SegmentTriangleDistance(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                                              const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                              const Eigen::Vector3d& c) {
  return SegmentTriangleSteps(s0, s1, a, b, c, nullptr, nullptr);
}

bool SegmentTriangleWithin(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                           const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c, double radius) {
  bool within = false;
  SegmentTriangleSteps(s0, s1, a, b, c, &radius, &within);
  return within;
}

}  // namespace sweptccd
