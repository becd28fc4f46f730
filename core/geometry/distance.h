#pragma once
// Exact closest-point queries between points, segments and triangles, in
// double precision. Degenerate inputs (zero-length segments, zero-area
// triangles) are handled: a degenerate triangle is the union of its edges.

#include <Eigen/Core>

namespace sweptccd {

/// Closest point to q on segment [p0, p1]; returns the parameter t in [0, 1]
/// with closest = p0 + t (p1 - p0).
double ClosestPointOnSegment(const Eigen::Vector3d& q, const Eigen::Vector3d& p0,
                             const Eigen::Vector3d& p1, Eigen::Vector3d* closest);

/// Squared distance between segments [p1, q1] and [p2, q2] with the closest
/// points c1 (on the first) and c2 (on the second).
double SegmentSegmentDistanceSquared(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
                                     const Eigen::Vector3d& p2, const Eigen::Vector3d& q2,
                                     Eigen::Vector3d* c1, Eigen::Vector3d* c2);

/// Closest point to p on triangle (a, b, c), which may be degenerate.
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c);

struct SegmentTriangleResult {
  double distance = 0;
  Eigen::Vector3d p_segment{0, 0, 0};   // Closest point on the segment.
  Eigen::Vector3d p_triangle{0, 0, 0};  // Closest point on the triangle.
};

/// Distance between segment [s0, s1] and triangle (a, b, c) with a pair of
/// closest points. Either may be degenerate. Zero when they intersect.
SegmentTriangleResult SegmentTriangleDistance(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                                              const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                              const Eigen::Vector3d& c);

/// SegmentTriangleDistance(s0, s1, a, b, c).distance <= radius, often
/// without the edge tests: a segment apart from the triangle by more than
/// radius (with a margin of 1e-9 of the magnitudes, far above the rounding)
/// along its plane's normal, an edge's outward normal in the plane, the
/// axis across the segment and an edge, or the axis from the vertex nearest
/// the segment, is refused; an end whose projection inside the triangle is
/// within radius is accepted; the rest are measured, up to the first
/// distance within radius. The same answer as the distance's, except where
/// the points lie farther from the origin than about 1e7 times the
/// triangle, segment and radius: the distance then rounds in absolute
/// coordinates by more than the margin, and a refusal (measured relative
/// to a vertex) is the more accurate answer. The test of the descent's
/// candidates (EnvironmentTarget::WithinCapsule).
bool SegmentTriangleWithin(const Eigen::Vector3d& s0, const Eigen::Vector3d& s1,
                           const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c, double radius);

/// True when the triangle's area is zero up to rounding (it is then treated as
/// the union of its three edges).
bool IsDegenerateTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c);

}  // namespace sweptccd
