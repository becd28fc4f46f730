// Randomised tests for core/distance.h against brute-force twins written here.
//
// The twins minimise the distance by golden-section search. Every distance
// below is convex in the parameters of the primitives (an affine map of a
// convex domain), and a partial minimum of a convex function is convex, so a
// golden-section search (nested for two parameters) converges to the global
// minimum; every value it returns is attained by real points, so it is an
// upper bound on the true minimum (up to the rounding of one evaluation).
//
// - PointSegmentSampled:  golden over the segment parameter.
// - PointTriangleSampled: nested golden over the barycentrics (u, v), v <= 1 - u.
// - SegmentSegmentSampled: nested golden over both segment parameters.
// - PointTriangleDirect: an independent closed form (projection onto the plane
//   when it falls inside, else the nearest of the three edges); itself checked
//   here against PointTriangleSampled.
// - SegmentTriangleSampled: golden over the segment parameter of
//   PointTriangleDirect, and on a subset the fully sampled triple search.
//
// Checks: the fast distance never exceeds the twin by more than 1e-12 of the
// case's scale (an overestimate could hide a contact), is not below the twin by
// more than the search resolution, and its closest points lie on their
// primitives at the returned distance.
//
// ccd_random_test.cc uses SegmentTriangleDistance in its reference once this
// file has validated it.

#include "core/geometry/distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace sweptccd {
namespace {

using Vec3 = Eigen::Vector3d;

// Golden-section search for the minimum of a convex f on [lo, hi]; returns the
// smallest value it evaluated (endpoints included) and its argument.
template <class F>
double GoldenMin(const F& f, double lo, double hi, int iterations, double* arg = nullptr) {
  constexpr double kInvPhi = 0.6180339887498949;
  double best = f(lo), best_x = lo;
  const double fhi = f(hi);
  if (fhi < best) {
    best = fhi;
    best_x = hi;
  }
  if (hi > lo) {
    double a = lo, b = hi;
    double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
    double f1 = f(x1), f2 = f(x2);
    for (int i = 0; i < iterations; ++i) {
      if (f1 < best) {
        best = f1;
        best_x = x1;
      }
      if (f2 < best) {
        best = f2;
        best_x = x2;
      }
      if (f1 <= f2) {
        b = x2;
        x2 = x1;
        f2 = f1;
        x1 = b - kInvPhi * (b - a);
        f1 = f(x1);
      } else {
        a = x1;
        x1 = x2;
        f1 = f2;
        x2 = a + kInvPhi * (b - a);
        f2 = f(x2);
      }
    }
    if (f1 < best) {
      best = f1;
      best_x = x1;
    }
    if (f2 < best) {
      best = f2;
      best_x = x2;
    }
  }
  if (arg != nullptr) *arg = best_x;
  return best;
}

constexpr int kIters = 70;  // 0.618^70 ~ 2e-15 of the parameter range.

double PointSegmentSampled(const Vec3& q, const Vec3& p0, const Vec3& p1) {
  return GoldenMin([&](double t) { return (p0 + t * (p1 - p0) - q).norm(); }, 0, 1, kIters);
}

// The closed form: clamped projection (zero-length segment: its point).
double PointSegmentDirect(const Vec3& q, const Vec3& p0, const Vec3& p1) {
  const Vec3 d = p1 - p0;
  const double dd = d.dot(d);
  double t = dd > 0 ? (q - p0).dot(d) / dd : 0;
  t = std::min(1.0, std::max(0.0, t));
  return (p0 + t * d - q).norm();
}

double PointTriangleSampled(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            int iterations = kIters) {
  const Vec3 ab = b - a, ac = c - a;
  return GoldenMin(
      [&](double u) {
        return GoldenMin([&](double v) { return (a + u * ab + v * ac - p).norm(); }, 0,
                         std::max(0.0, 1 - u), iterations);
      },
      0, 1, iterations);
}

// In long double: for a sliver of height h (relative to its longest edge) the
// computed normal is off by about 1e-19 / h, so below h = 1e-9 the edges alone
// are used (they are then within h of the answer).
double PointTriangleDirect(const Vec3& p_in, const Vec3& a_in, const Vec3& b_in, const Vec3& c_in) {
  const double edges =
      std::min({PointSegmentDirect(p_in, a_in, b_in), PointSegmentDirect(p_in, b_in, c_in),
                PointSegmentDirect(p_in, c_in, a_in)});
  using V = Eigen::Matrix<long double, 3, 1>;
  const V p = p_in.cast<long double>(), a = a_in.cast<long double>(), b = b_in.cast<long double>(),
          c = c_in.cast<long double>();
  const V n = (b - a).cross(c - a);
  const long double nn = n.squaredNorm();
  const long double longest2 =
      std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  // |n| = longest * height: skip the face when height < 1e-9 * longest.
  if (!(nn > 1e-18L * longest2 * longest2)) return edges;
  const V x = p - ((p - a).dot(n) / nn) * n;  // Projection onto the plane.
  const bool inside = n.dot((b - a).cross(x - a)) >= 0 && n.dot((c - b).cross(x - b)) >= 0 &&
                      n.dot((a - c).cross(x - c)) >= 0;
  if (!inside) return edges;
  return std::min(edges, static_cast<double>(std::fabs((p - a).dot(n)) / std::sqrt(nn)));
}

double SegmentSegmentSampled(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  return GoldenMin(
      [&](double s) {
        const Vec3 x = p1 + s * (q1 - p1);
        return GoldenMin([&](double t) { return (p2 + t * (q2 - p2) - x).norm(); }, 0, 1, kIters);
      },
      0, 1, kIters);
}

double SegmentTriangleSampled(const Vec3& s0, const Vec3& s1, const Vec3& a, const Vec3& b,
                              const Vec3& c) {
  return GoldenMin([&](double t) { return PointTriangleDirect(s0 + t * (s1 - s0), a, b, c); }, 0, 1,
                   100);
}

double SegmentTriangleFullySampled(const Vec3& s0, const Vec3& s1, const Vec3& a, const Vec3& b,
                                   const Vec3& c) {
  return GoldenMin([&](double t) { return PointTriangleSampled(s0 + t * (s1 - s0), a, b, c, 50); },
                   0, 1, 50);
}

// ---------------------------------------------------------------------------
// Random cases.

struct Gen {
  explicit Gen(uint64_t seed) : rng(seed) {}
  std::mt19937_64 rng;
  double U(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  int I(int n) { return static_cast<int>(rng() % static_cast<uint64_t>(n)); }
  Vec3 Box(double half) { return Vec3(U(-half, half), U(-half, half), U(-half, half)); }
  Vec3 Dir() {
    std::normal_distribution<double> g;
    Vec3 v(g(rng), g(rng), g(rng));
    return v.normalized();
  }
  Vec3 Perp(const Vec3& d) {
    Vec3 v = Dir();
    v -= v.dot(d) * d / std::max(d.squaredNorm(), 1e-300);
    return v.norm() > 0 ? v.normalized() : Vec3(1, 0, 0);
  }
  // A scale in [1e-3, 1e2] metres and an offset of a few scales.
  void NewScale() {
    scale = std::pow(10.0, U(-3, 2));
    centre = scale * Box(3);
  }
  Vec3 Point() { return centre + scale * Box(1); }
  double scale = 1;
  Vec3 centre{0, 0, 0};
};

double MaxAbs(std::initializer_list<Vec3> points) {
  double m = 0;
  for (const Vec3& p : points) m = std::max(m, p.cwiseAbs().maxCoeff());
  return m;
}

std::string Fmt(const Vec3& v) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), "[%.17g, %.17g, %.17g]", v.x(), v.y(), v.z());
  return buf;
}

// A triangle: general, degenerate (collinear, repeated vertices, a point) or a
// sliver below or near the degeneracy threshold.
void RandomTriangle(Gen& g, Vec3* a, Vec3* b, Vec3* c, std::string* kind) {
  *a = g.Point();
  *b = g.Point();
  *c = g.Point();
  const int k = g.I(10);
  if (k == 0) {
    *kind = "collinear";
    *c = *a + g.U(-1, 2) * (*b - *a);
  } else if (k == 1) {
    *kind = "repeated";
    const int which = g.I(3);
    if (which == 0) *b = *a;
    if (which == 1) *c = *b;
    if (which == 2) *a = *c;
  } else if (k == 2) {
    *kind = "point";
    *b = *a;
    *c = *a;
  } else if (k == 3) {
    *kind = "sliver";
    const Vec3 d = *b - *a;
    *c = *a + g.U(-0.5, 1.5) * d + std::pow(10.0, g.U(-16, -6)) * d.norm() * g.Perp(d);
  } else if (k == 4) {
    *kind = "axis-collinear";
    *b = *a;
    *c = *a;
    const int axis = g.I(3);
    (*b)[axis] += g.scale * g.U(-1, 1);
    (*c)[axis] += g.scale * g.U(-1, 1);
  } else {
    *kind = "general";
  }
}

// A segment relative to the triangle: random, crossing it, coplanar with it,
// touching it, just above its face, or of zero length.
void RandomSegment(Gen& g, const Vec3& a, const Vec3& b, const Vec3& c, Vec3* s0, Vec3* s1,
                   std::string* kind) {
  *s0 = g.Point();
  *s1 = g.Point();
  const double u = g.U(0, 1), v = g.U(0, 1 - u);
  const Vec3 x = a + u * (b - a) + v * (c - a);  // A point of the triangle.
  Vec3 n = (b - a).cross(c - a);
  n = n.norm() > 0 ? n.normalized() : g.Dir();
  const int k = g.I(8);
  if (k == 0) {
    *kind = "crossing";
    const Vec3 d = g.Dir() * g.scale;
    *s0 = x - g.U(0, 1) * d;
    *s1 = x + g.U(0, 1) * d;
  } else if (k == 1) {
    *kind = "coplanar";
    auto on_plane = [&]() {
      const double uu = g.U(-0.5, 1.5), vv = g.U(-0.5, 1.5);
      return a + uu * (b - a) + vv * (c - a);
    };
    *s0 = on_plane();
    *s1 = on_plane();
  } else if (k == 2) {
    *kind = "endpoint-on-triangle";
    *s0 = x;
  } else if (k == 3) {
    *kind = "just-above";
    const double h = g.scale * std::pow(10.0, g.U(-12, -2));
    const Vec3 t = g.Perp(n) * g.scale;
    *s0 = x + h * n - g.U(0, 1) * t;
    *s1 = x + h * n + g.U(0, 1) * t;
  } else if (k == 4) {
    *kind = "zero-length";
    *s1 = *s0;
  } else if (k == 5) {
    *kind = "parallel-to-edge";
    const Vec3 e = b - a;
    const Vec3 off = g.scale * std::pow(10.0, g.U(-9, 0)) * g.Perp(e);
    *s0 = a + off + g.U(-0.5, 0.5) * e;
    *s1 = *s0 + g.U(0.1, 1.5) * e * (1 + std::pow(10.0, g.U(-12, -3)) * g.U(-1, 1));
  } else {
    *kind = "random";
  }
}

// ---------------------------------------------------------------------------

// Collects every check of a randomised run instead of stopping at the first
// failure, so a failing run says how often and how badly each property fails
// and prints the worst case (ready to paste into a regression test).
class Checks {
 public:
  explicit Checks(std::string title) : title_(std::move(title)) {}
  // Records `excess` (how far past the allowed bound; <= 0 passes), relative
  // to the case's scale.
  void Check(const std::string& name, double excess_rel, const std::function<std::string()>& what) {
    Stat& st = stats_[name];
    ++st.checked;
    if (!(excess_rel <= 0)) {  // NaN fails too.
      ++st.failed;
      if (!(excess_rel <= st.worst)) {
        st.worst = excess_rel;
        st.worst_case = what();
      }
    }
  }
  void Report() const {
    for (const auto& [name, st] : stats_) {
      std::printf("%s / %s: %lld checked, %lld failed\n", title_.c_str(), name.c_str(),
                  static_cast<long long>(st.checked), static_cast<long long>(st.failed));
      EXPECT_EQ(st.failed, 0) << title_ << " / " << name << ": " << st.failed << " of "
                              << st.checked << " cases fail; worst excess " << st.worst
                              << " (relative to the scale) in\n  " << st.worst_case;
    }
  }

 private:
  struct Stat {
    int64_t checked = 0, failed = 0;
    double worst = -1;
    std::string worst_case;
  };
  std::string title_;
  std::map<std::string, Stat> stats_;
};

// The bounds, relative to the largest coordinate of the case.
// Floating point cannot do 1e-12 on slivers (a plane known to ~1e-16 L / h
// radians) or near-parallel segments. The routines keep errors below 1e-8 of
// the coordinates' magnitude (measured worst: 2.7e-9); the engine treats
// anything within 2^-22 (2.4e-7) of that magnitude as touching, 24 times more,
// so these errors can never hide a contact.
constexpr double kOverRel = 1e-8;    // Fast above the twin: would hide contacts.
constexpr double kUnderRel = 1e-9;   // Fast below the twin: the twin's resolution.
constexpr double kPointRel = 1e-8;   // Closest points on their primitives.

TEST(DistanceTest, ClosestPointOnSegmentMatchesTwin) {
  Gen g(0x5e6d157ULL);
  Checks checks("ClosestPointOnSegment");
  for (int i = 0; i < 100000; ++i) {
    g.NewScale();
    Vec3 q = g.Point(), p0 = g.Point(), p1 = g.Point();
    if (i % 10 == 0) p1 = p0;                                             // Zero length.
    if (i % 10 == 1) q = p0 + g.U(-0.5, 1.5) * (p1 - p0);                 // On the line.
    if (i % 10 == 2) p1 = p0 + (p1 - p0) * std::pow(10.0, g.U(-12, -4));  // Tiny.
    const double scale = std::max(MaxAbs({q, p0, p1}), g.scale);
    Vec3 closest;
    const double t = ClosestPointOnSegment(q, p0, p1, &closest);
    const double fast = (closest - q).norm();
    const double twin = PointSegmentSampled(q, p0, p1);
    auto what = [&] {
      std::ostringstream os;
      os << "case " << i << " q=" << Fmt(q) << " p0=" << Fmt(p0) << " p1=" << Fmt(p1)
         << " fast=" << fast << " twin=" << twin << " t=" << t;
      return os.str();
    };
    checks.Check("t in [0, 1]", (t < 0 || t > 1) ? 1.0 : -1.0, what);
    checks.Check("closest == p0 + t (p1 - p0)",
                 (closest - (p0 + t * (p1 - p0))).norm() / scale - 1e-14, what);
    checks.Check("not above twin", (fast - twin) / scale - kOverRel, what);
    checks.Check("not below twin", (twin - fast) / scale - kUnderRel, what);
    checks.Check("closed form agrees",
                 std::fabs(PointSegmentDirect(q, p0, p1) - twin) / scale - kUnderRel, what);
  }
  checks.Report();
}

TEST(DistanceTest, SegmentSegmentDistanceMatchesTwin) {
  Gen g(0x5e65e6ULL);
  Checks checks("SegmentSegmentDistanceSquared");
  for (int i = 0; i < 100000; ++i) {
    g.NewScale();
    Vec3 p1 = g.Point(), q1 = g.Point(), p2 = g.Point(), q2 = g.Point();
    std::string kind = "random";
    const int k = i % 8;
    if (k == 0) {
      kind = "near-parallel";
      const Vec3 d = q1 - p1;
      p2 = p1 + g.U(-1, 1) * d + g.scale * std::pow(10.0, g.U(-9, 0)) * g.Perp(d);
      q2 = p2 + g.U(-1.5, 1.5) * d + d.norm() * std::pow(10.0, g.U(-14, -3)) * g.Dir();
    } else if (k == 1) {
      kind = "exactly-parallel";
      const Vec3 d = q1 - p1;
      p2 = p1 + g.scale * std::pow(10.0, g.U(-9, 0)) * g.Perp(d);
      q2 = p2 + g.U(-2, 2) * d;
    } else if (k == 2) {
      kind = "crossing";
      const Vec3 x = p1 + g.U(0, 1) * (q1 - p1);
      const Vec3 d = g.Dir() * g.scale;
      p2 = x - g.U(0, 1) * d;
      q2 = x + g.U(0, 1) * d;
    } else if (k == 3) {
      kind = "zero-length";
      if (g.I(2)) q1 = p1;
      if (g.I(2)) q2 = p2;
    } else if (k == 4) {
      kind = "collinear";
      const Vec3 d = q1 - p1;
      p2 = p1 + g.U(-2, 2) * d;
      q2 = p1 + g.U(-2, 2) * d;
    } else if (k == 5) {
      kind = "coplanar";
      const Vec3 e1 = (q1 - p1), e2 = g.Perp(e1) * e1.norm();
      p2 = p1 + g.U(-1, 2) * e1 + g.U(-1, 1) * e2;
      q2 = p1 + g.U(-1, 2) * e1 + g.U(-1, 1) * e2;
    }
    const double scale = std::max(MaxAbs({p1, q1, p2, q2}), g.scale);
    Vec3 c1, c2;
    const double d2 = SegmentSegmentDistanceSquared(p1, q1, p2, q2, &c1, &c2);
    const double fast = std::sqrt(d2);
    const double twin = SegmentSegmentSampled(p1, q1, p2, q2);
    auto what = [&] {
      std::ostringstream os;
      os.precision(17);
      os << "case " << i << " (" << kind << ") p1=" << Fmt(p1) << " q1=" << Fmt(q1)
         << " p2=" << Fmt(p2) << " q2=" << Fmt(q2) << " fast=" << fast << " twin=" << twin;
      return os.str();
    };
    checks.Check("finite", std::isfinite(d2) ? -1.0 : 1.0, what);
    checks.Check("not above twin", (fast - twin) / scale - kOverRel, what);
    checks.Check("not below twin", (twin - fast) / scale - kUnderRel, what);
    checks.Check("|c1 - c2| == distance", std::fabs((c1 - c2).norm() - fast) / scale - kPointRel,
                 what);
    checks.Check("c1 on segment 1", PointSegmentDirect(c1, p1, q1) / scale - kPointRel, what);
    checks.Check("c2 on segment 2", PointSegmentDirect(c2, p2, q2) / scale - kPointRel, what);
  }
  checks.Report();
}

TEST(DistanceTest, ClosestPointOnTriangleMatchesTwin) {
  Gen g(0x7a1a6e1eULL);
  Checks checks("ClosestPointOnTriangle");
  for (int i = 0; i < 100000; ++i) {
    g.NewScale();
    Vec3 a, b, c;
    std::string kind;
    RandomTriangle(g, &a, &b, &c, &kind);
    Vec3 p = g.Point();
    const int k = i % 5;
    if (k == 0) {  // Near the face.
      const double u = g.U(0, 1), v = g.U(0, 1 - u);
      Vec3 n = (b - a).cross(c - a);
      n = n.norm() > 0 ? n.normalized() : g.Dir();
      p = a + u * (b - a) + v * (c - a) + g.scale * std::pow(10.0, g.U(-12, 0)) * g.U(-1, 1) * n;
    } else if (k == 1) {  // In the plane, maybe outside.
      p = a + g.U(-1, 2) * (b - a) + g.U(-1, 2) * (c - a);
    }
    const double scale = std::max(MaxAbs({p, a, b, c}), g.scale);
    const Vec3 x = ClosestPointOnTriangle(p, a, b, c);
    const double fast = (x - p).norm();
    const double twin = PointTriangleSampled(p, a, b, c);
    const double direct = PointTriangleDirect(p, a, b, c);
    auto what = [&] {
      std::ostringstream os;
      os.precision(17);
      os << "case " << i << " (" << kind << ") p=" << Fmt(p) << " a=" << Fmt(a) << " b=" << Fmt(b)
         << " c=" << Fmt(c) << " fast=" << fast << " twin=" << twin << " direct=" << direct;
      return os.str();
    };
    checks.Check("not above twin", (fast - twin) / scale - kOverRel, what);
    checks.Check("not below twin", (twin - fast) / scale - kUnderRel, what);
    checks.Check("point on triangle", PointTriangleDirect(x, a, b, c) / scale - kPointRel, what);
    // The closed-form twin used by SegmentTriangleSampled agrees with sampling.
    checks.Check("closed-form twin agrees", std::fabs(direct - twin) / scale - kUnderRel, what);
  }
  checks.Report();
}

void CheckSegmentTriangle(int cases, uint64_t seed, bool fully_sampled) {
  Gen g(seed);
  Checks checks(fully_sampled ? "SegmentTriangleDistance vs triple golden"
                              : "SegmentTriangleDistance");
  for (int i = 0; i < cases; ++i) {
    g.NewScale();
    Vec3 a, b, c, s0, s1;
    std::string tri_kind, seg_kind;
    RandomTriangle(g, &a, &b, &c, &tri_kind);
    RandomSegment(g, a, b, c, &s0, &s1, &seg_kind);
    const double scale = std::max(MaxAbs({s0, s1, a, b, c}), g.scale);
    const SegmentTriangleResult r = SegmentTriangleDistance(s0, s1, a, b, c);
    const double twin = fully_sampled ? SegmentTriangleFullySampled(s0, s1, a, b, c)
                                      : SegmentTriangleSampled(s0, s1, a, b, c);
    auto what = [&] {
      std::ostringstream os;
      os.precision(17);
      os << "case " << i << " (" << tri_kind << ", " << seg_kind << ") s0=" << Fmt(s0)
         << " s1=" << Fmt(s1) << " a=" << Fmt(a) << " b=" << Fmt(b) << " c=" << Fmt(c)
         << " fast=" << r.distance << " twin=" << twin;
      return os.str();
    };
    checks.Check("finite, >= 0", std::isfinite(r.distance) && r.distance >= 0 ? -1.0 : 1.0, what);
    checks.Check("not above twin", (r.distance - twin) / scale - kOverRel, what);
    // The triple golden search (50 iterations a level) is coarser.
    checks.Check("not below twin", (twin - r.distance) / scale - (fully_sampled ? 1e-7 : kUnderRel),
                 what);
    checks.Check("|p_segment - p_triangle| == distance",
                 std::fabs((r.p_segment - r.p_triangle).norm() - r.distance) / scale - kPointRel,
                 what);
    checks.Check("p_segment on segment",
                 PointSegmentDirect(r.p_segment, s0, s1) / scale - kPointRel, what);
    checks.Check("p_triangle on triangle",
                 PointTriangleDirect(r.p_triangle, a, b, c) / scale - kPointRel, what);
  }
  checks.Report();
}

TEST(DistanceTest, SegmentTriangleDistanceMatchesTwin) {
  CheckSegmentTriangle(100000, 0x5e67a1ULL, false);
}

TEST(DistanceTest, SegmentTriangleDistanceMatchesFullySampledTwin) {
  CheckSegmentTriangle(1500, 0xf011ULL, true);
}

// SegmentTriangleWithin gives SegmentTriangleDistance(...).distance <= r on
// every case: the random triangles and segments above (slivers, degenerate
// triangles, crossing, grazing and zero-length segments, scales 1e-3 to
// 1e2 m), each at radii around its distance (the distance, one step either
// side, relative 1e-12, 1e-6 and 1e-3 either side, half, double) and around
// its ends' distances to the plane, beyond each edge, across the segment
// and each edge, and from the vertex nearest the segment, where the early
// refusals decide.
TEST(DistanceTest, SegmentTriangleWithinGivesTheDistancesAnswer) {
  Gen g(0x3171a5ULL);
  int disagreements = 0, tested = 0;
  std::string first;
  for (int i = 0; i < 200000; ++i) {
    g.NewScale();
    Vec3 a, b, c, s0, s1;
    std::string tri_kind, seg_kind;
    RandomTriangle(g, &a, &b, &c, &tri_kind);
    RandomSegment(g, a, b, c, &s0, &s1, &seg_kind);
    const double d = SegmentTriangleDistance(s0, s1, a, b, c).distance;
    std::vector<double> radii = {d,
                                 std::nextafter(d, 0.0),
                                 std::nextafter(d, HUGE_VAL),
                                 d * (1 - 1e-12),
                                 d * (1 + 1e-12),
                                 d * (1 - 1e-6),
                                 d * (1 + 1e-6),
                                 d * (1 - 1e-3),
                                 d * (1 + 1e-3),
                                 0.5 * d,
                                 2 * d};
    // Radii at a refusal's gap h and just either side of it, where it decides.
    auto around = [&radii](double h) {
      for (double r : {h, h * (1 - 1e-9), h * (1 + 1e-9), h * (1 - 1e-6), h * (1 + 1e-6)}) {
        radii.push_back(r);
      }
    };
    // The gap between the segment's and the triangle's projections on the
    // unit axis u (<= 0 where they overlap).
    auto gap_along = [&](const Vec3& u) {
      const double s_lo = std::min(u.dot(s0), u.dot(s1)), s_hi = std::max(u.dot(s0), u.dot(s1));
      const double t_lo = std::min({u.dot(a), u.dot(b), u.dot(c)});
      const double t_hi = std::max({u.dot(a), u.dot(b), u.dot(c)});
      return std::max(s_lo - t_hi, t_lo - s_hi);
    };
    const Vec3 n = (b - a).cross(c - a);
    if (n.norm() > 0) {
      for (const Vec3& e : {s0, s1}) around(std::fabs(n.normalized().dot(e - a)));
      // How far the nearer end lies beyond each edge, in the plane: where
      // the edge refusal decides.
      const Vec3* v[3] = {&a, &b, &c};
      for (int k = 0; k < 3; ++k) {
        const Vec3 out = (*v[(k + 1) % 3] - *v[k]).cross(n.normalized()).normalized();
        around(std::min(out.dot(s0 - *v[k]), out.dot(s1 - *v[k])));
      }
    }
    // How far apart the segment and the triangle lie along each axis across
    // the segment and an edge: where that refusal decides.
    for (int k = 0; k < 3; ++k) {
      const Vec3* v[3] = {&a, &b, &c};
      const Vec3 m = (s1 - s0).cross(*v[(k + 1) % 3] - *v[k]);
      if (m.norm() > 0) around(gap_along(m.normalized()));
    }
    // How far apart they lie along the axis from the vertex nearest the
    // segment to its nearest point there: where that refusal decides.
    {
      const Vec3 d = s1 - s0;
      Vec3 axis(0, 0, 0);
      double nearest = HUGE_VAL;
      for (const Vec3& v : {a, b, c}) {
        const double t =
            d.squaredNorm() > 0 ? std::clamp((v - s0).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
        const Vec3 w = v - (s0 + t * d);
        if (w.squaredNorm() < nearest) {
          nearest = w.squaredNorm();
          axis = w;
        }
      }
      if (axis.norm() > 0) around(gap_along(axis.normalized()));
    }
    for (double r : radii) {
      if (!(r > 0)) continue;
      ++tested;
      const bool within = SegmentTriangleWithin(s0, s1, a, b, c, r);
      if (within != (d <= r)) {
        if (disagreements++ == 0) {
          std::ostringstream os;
          os.precision(17);
          os << "case " << i << " (" << tri_kind << ", " << seg_kind << ") s0=" << Fmt(s0)
             << " s1=" << Fmt(s1) << " a=" << Fmt(a) << " b=" << Fmt(b) << " c=" << Fmt(c)
             << " distance=" << d << " radius=" << r << " within=" << within;
          first = os.str();
        }
      }
    }
  }
  EXPECT_GT(tested, 2000000);
  EXPECT_EQ(disagreements, 0) << "first: " << first;
}

// A segment parallel to an edge but for a component of 2.72e-162 m: the
// cross product of its direction with that edge has a subnormal square, so
// a length taken as the square root of the squared norm is off by up to
// 22 % and an axis divided by it is too long. The distance is 10 m; a
// refusal along such an axis said "apart" up to a radius of 12.2 m.
TEST(DistanceTest, SegmentTriangleWithinWithASubnormalCrossProduct) {
  const Vec3 a(0, -1, 0), b(1, -1, 0), c(0, 1, 0);
  const Vec3 s0(0.25, 0, 10), s1(1.25, 2.72e-162, 10);
  const double d = SegmentTriangleDistance(s0, s1, a, b, c).distance;
  EXPECT_EQ(d, 10.0);
  for (double r : {10.0, 10.2, 11.0, 12.0, 12.2}) {
    EXPECT_TRUE(SegmentTriangleWithin(s0, s1, a, b, c, r)) << r;
  }
  EXPECT_FALSE(SegmentTriangleWithin(s0, s1, a, b, c, std::nextafter(10.0, 0.0)));
}

// Segments nearly parallel to an axis-aligned edge, off it in one
// coordinate by 0 or +-1e-170 to 1e-140 (exactly representable: that
// coordinate is 0 at the start), so that the cross products of the
// segment with the edges have squares near or below the subnormal range;
// axes permuted at random. SegmentTriangleWithin still gives the
// distance's answer at radii around the distance.
TEST(DistanceTest, SegmentTriangleWithinWithTinyComponents) {
  Gen g(0x7195ULL);
  int disagreements = 0, tested = 0;
  std::string first;
  for (int i = 0; i < 20000; ++i) {
    const double len = std::pow(10.0, g.U(-2, 1));
    Vec3 a(0, 0, 0), b(len * g.U(0.2, 2), 0, 0), c(g.U(-1, 1), g.U(0.1, 2), 0);
    c *= len;
    const double tiny = g.I(4) == 0 ? 0.0 : (g.I(2) ? 1 : -1) * std::pow(10.0, g.U(-170, -140));
    const double x0 = len * g.U(-1, 2), z = len * g.U(-2, 2) * (g.I(4) == 0 ? 0 : 1);
    // The start's second coordinate is 0 (on the edge's line, or off it only
    // in the third); the end is off by `tiny` there.
    Vec3 s0(x0, 0, z), s1(x0 + len * g.U(0.1, 2), tiny, z);
    if (g.I(2)) std::swap(s0, s1);
    const int perm = g.I(6);
    auto permute = [perm](Vec3 v) {
      static const int order[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
      return Vec3(v[order[perm][0]], v[order[perm][1]], v[order[perm][2]]);
    };
    a = permute(a), b = permute(b), c = permute(c), s0 = permute(s0), s1 = permute(s1);
    const double d = SegmentTriangleDistance(s0, s1, a, b, c).distance;
    for (double r : {d, d * (1 - 1e-9), d * (1 + 1e-9), d * (1 + 1e-6), d * 1.1, d * 1.25}) {
      if (!(r > 0)) continue;
      ++tested;
      const bool within = SegmentTriangleWithin(s0, s1, a, b, c, r);
      if (within != (d <= r) && disagreements++ == 0) {
        std::ostringstream os;
        os.precision(17);
        os << "case " << i << " s0=" << Fmt(s0) << " s1=" << Fmt(s1) << " a=" << Fmt(a)
           << " b=" << Fmt(b) << " c=" << Fmt(c) << " distance=" << d << " radius=" << r
           << " within=" << within;
        first = os.str();
      }
    }
  }
  EXPECT_GT(tested, 80000);
  EXPECT_EQ(disagreements, 0) << "first: " << first;
}

// The two early answers on a floor: a segment above a large triangle is
// refused by the plane when the radius falls short of its height, and
// accepted by its end's projection when the radius reaches it; the answers
// are the distance's (0.1 m).
TEST(DistanceTest, SegmentTriangleWithinAboveAFloor) {
  const Vec3 a(-10, 0, -10), b(10, 0, -10), c(0, 0, 10);
  const Vec3 s0(0.3, 0.1, 0.2), s1(0.3, 0.4, 0.5);
  const double d = SegmentTriangleDistance(s0, s1, a, b, c).distance;
  EXPECT_NEAR(d, 0.1, 1e-15);
  for (double r : {0.05, 0.0999, d, 0.1001, 0.2}) {
    EXPECT_EQ(SegmentTriangleWithin(s0, s1, a, b, c, r), d <= r) << r;
  }
  EXPECT_FALSE(SegmentTriangleWithin(s0, s1, a, b, c, 0.0999));
  EXPECT_TRUE(SegmentTriangleWithin(s0, s1, a, b, c, 0.1001));
}

// The edge refusal: a segment in the triangle's plane band, 0.1 m beyond its
// edge ab (and nearest that edge), is refused when the radius falls short of
// 0.1 m and accepted when it reaches it; the answers are the distance's.
TEST(DistanceTest, SegmentTriangleWithinBesideAnEdge) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0.5, 0, 1);
  const Vec3 s0(0.3, 0.05, -0.1), s1(0.6, -0.02, -0.1);
  const double d = SegmentTriangleDistance(s0, s1, a, b, c).distance;
  EXPECT_NEAR(d, 0.1, 1e-15);
  for (double r : {0.05, 0.0999, std::nextafter(d, 0.0), d, 0.1001, 0.2}) {
    EXPECT_EQ(SegmentTriangleWithin(s0, s1, a, b, c, r), d <= r) << r;
  }
  EXPECT_FALSE(SegmentTriangleWithin(s0, s1, a, b, c, 0.0999));
  EXPECT_TRUE(SegmentTriangleWithin(s0, s1, a, b, c, 0.1001));
}

// Regressions (minimised from the randomised runs above).

// Near-parallel segments (angle 5e-8 rad) whose closest points are inside
// both: the closed form is ill-conditioned and the endpoint fallback alone
// answered 5.1e-8 for a true distance of 1e-8.
TEST(DistanceTest, NearParallelSegmentsInteriorMinimum) {
  Vec3 c1, c2;
  const double d = std::sqrt(SegmentSegmentDistanceSquared(
      Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(4, -5e-8, 1e-8), Vec3(6, 5e-8, 1e-8), &c1, &c2));
  EXPECT_NEAR(d, 1e-8, 1e-12 * 10);
  EXPECT_NEAR(SegmentTriangleDistance(Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(4, -5e-8, 1e-8),
                                      Vec3(6, 5e-8, 1e-8), Vec3(5, 0, 5))
                  .distance,
              1e-8, 1e-12 * 10);
}

// A point inside a 1 m sliver of height 2^-18 (3.8e-6) m: the Voronoi-region
// barycentrics lost ~1e-7 m (answers 1.4e-7 and 5.5e-7 for distance 0).
TEST(DistanceTest, PointInsideSliverOfHeight4Micrometres) {
  const double h = std::ldexp(1.0, -18);
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0.5, h, 0);
  for (const Vec3& p : {Vec3(0.3, 0.3 * h, 0), Vec3(0.201, 5.7506561279296873e-07, 0)}) {
    EXPECT_LE((ClosestPointOnTriangle(p, a, b, c) - p).norm(), 1e-12) << Fmt(p);
    EXPECT_LE(SegmentTriangleDistance(p, p, a, b, c).distance, 1e-12) << Fmt(p);
  }
}

// Thinner slivers (height 1e-9 of a 1 m edge) are answered as their edges:
// a point 1e-13 above the face gets ~h / 2 = 5e-10 (1e-10 here). Within the
// environment's coordinate tolerance (2^-23 of the coordinates), so no miss
// follows, but above the 1e-12 relative bound this file asks of distances.
TEST(DistanceTest, PointAboveSliverOfHeight1Nanometre) {
  const double h = 1e-9;
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0.5, h, 0), p(0.3, 0.5 * h, 1e-13);
  // A sliver this thin (h / L = 1e-9, below the 1e-8 threshold) is treated as
  // its edges: the answer may be off by at most its height, 1e-8 of its
  // length, which the engine's tolerance (2^-22 of the coordinates) covers.
  const double d = (ClosestPointOnTriangle(p, a, b, c) - p).norm();
  EXPECT_LE(d, 1e-13 + h);
  EXPECT_GE(d, 1e-13 - 1e-15);
}

// Hand-made cases with known answers.
TEST(DistanceTest, KnownCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Crossing the face.
  EXPECT_EQ(SegmentTriangleDistance(Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), a, b, c).distance, 0);
  // Touching the face with an endpoint.
  EXPECT_EQ(SegmentTriangleDistance(Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 1), a, b, c).distance, 0);
  // Above the face, parallel.
  EXPECT_NEAR(SegmentTriangleDistance(Vec3(0.1, 0.1, 0.5), Vec3(0.3, 0.1, 0.5), a, b, c).distance,
              0.5, 1e-15);
  // Touching a vertex.
  EXPECT_EQ(SegmentTriangleDistance(Vec3(-1, 0, 0), Vec3(0, 0, 0), a, b, c).distance, 0);
  // Point triangle (all vertices equal), segment passing at 0.25.
  const Vec3 p(0.5, 0.5, 0.5);
  EXPECT_NEAR(SegmentTriangleDistance(Vec3(0, 0.75, 0.5), Vec3(1, 0.75, 0.5), p, p, p).distance,
              0.25, 1e-15);
  // Collinear triangle crossed by a segment.
  EXPECT_EQ(
      SegmentTriangleDistance(Vec3(0.5, -1, 0), Vec3(0.5, 1, 0), a, b, Vec3(2, 0, 0)).distance, 0);
  // Zero-length segment against a point.
  EXPECT_NEAR(SegmentTriangleDistance(Vec3(0, 0, 3), Vec3(0, 0, 3), p, p, p).distance,
              std::sqrt(0.25 + 0.25 + 6.25), 1e-15);
  // Segment in the plane of the face, crossing an edge.
  EXPECT_NEAR(SegmentTriangleDistance(Vec3(-1, 0.3, 0), Vec3(2, 0.3, 0), a, b, c).distance, 0,
              1e-15);
  EXPECT_TRUE(IsDegenerateTriangle(a, b, Vec3(3, 0, 0)));
  EXPECT_TRUE(IsDegenerateTriangle(a, a, a));
  EXPECT_FALSE(IsDegenerateTriangle(a, b, c));
}

}  // namespace
}  // namespace sweptccd
