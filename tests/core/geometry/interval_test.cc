// Randomised enclosure tests for core/interval.h.
//
// The brute-force twin of every interval operation is the same operation on
// points of the operands, computed in long double (64-bit mantissa). That
// reference is not exact, but its relative error (2^-64) is far below the
// margin (about 2^-54 relative) that one ulp of outward rounding leaves between
// the exact result and the interval's ends, so a point outside the interval is
// a real enclosure failure, not noise of the reference.

#include "core/geometry/interval.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace sweptccd {
namespace {

using LD = long double;

constexpr LD kPiL = 3.141592653589793238462643383279502884L;
constexpr double kPiD = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Counts enclosure checks and keeps the first few failures for the message.
struct Tally {
  int64_t checks = 0;
  int64_t violations = 0;
  std::string first;

  // `what` is a callable that returns the description (built only on failure).
  template <typename What>
  void Check(bool ok, const What& what) {
    ++checks;
    if (ok) return;
    ++violations;
    if (violations <= 5) first += what() + "\n";
  }
};

std::string Describe(const Interval& x) {
  std::ostringstream s;
  s.precision(17);
  s << "[" << x.lo() << ", " << x.hi() << "]";
  return s.str();
}

std::string Num(LD v) {
  std::ostringstream s;
  s.precision(21);
  s << v;
  return s.str();
}

bool Encloses(const Interval& r, LD v) {
  return static_cast<LD>(r.lo()) <= v && v <= static_cast<LD>(r.hi());
}

// The bits of a double, for bit-for-bit comparisons.
uint64_t Bits(double v) {
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// A random double from a mix of scales: ordinary, huge, tiny, subnormal,
// integers, and values next to multiples of pi/2 (where sin/cos turn or vanish).
double RandomValue(std::mt19937_64& g) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_int_distribution<int> kind(0, 7);
  const double sign = u01(g) < 0.5 ? -1.0 : 1.0;
  switch (kind(g)) {
    case 0:
      return std::uniform_real_distribution<double>(-10, 10)(g);
    case 1:  // Huge and tiny magnitudes.
      return sign * std::pow(10.0, std::uniform_real_distribution<double>(-300, 300)(g));
    case 2:
      return sign * std::pow(10.0, std::uniform_real_distribution<double>(-20, 20)(g));
    case 3:
      return static_cast<double>(std::uniform_int_distribution<int>(-20, 20)(g));
    case 4:  // Zero and subnormals.
      return sign *
             std::ldexp(static_cast<double>(std::uniform_int_distribution<int>(0, 1000)(g)), -1074);
    case 5: {  // Near m * pi/2, a few ulps or a tiny offset away.
      const int m = std::uniform_int_distribution<int>(-12, 12)(g);
      double v = static_cast<double>(m * kPiL / 2);
      const int steps = std::uniform_int_distribution<int>(-4, 4)(g);
      for (int k = 0; k < std::abs(steps); ++k) v = std::nextafter(v, steps < 0 ? -kInf : kInf);
      if (u01(g) < 0.3)
        v += sign * std::pow(10.0, std::uniform_real_distribution<double>(-18, -3)(g));
      return v;
    }
    case 6:  // Large but with sin/cos still meaningful.
      return sign * std::pow(10.0, std::uniform_real_distribution<double>(3, 17)(g));
    default:
      return std::uniform_real_distribution<double>(-1, 1)(g);
  }
}

// A random finite interval around a random value: a point, a few ulps, a
// relative or absolute width, or the hull of two random values.
Interval RandomInterval(std::mt19937_64& g) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (;;) {
    const double a = RandomValue(g);
    double b = a;
    switch (std::uniform_int_distribution<int>(0, 4)(g)) {
      case 0:
        break;
      case 1: {
        const int n = std::uniform_int_distribution<int>(1, 8)(g);
        for (int k = 0; k < n; ++k) b = std::nextafter(b, kInf);
        break;
      }
      case 2:
        b = a + std::fabs(a) * std::pow(10.0, std::uniform_real_distribution<double>(-16, 0)(g));
        break;
      case 3:
        b = a + std::pow(10.0, std::uniform_real_distribution<double>(-300, 300)(g)) * u01(g);
        break;
      default:
        b = RandomValue(g);
        break;
    }
    if (!std::isfinite(a) || !std::isfinite(b)) continue;
    return Interval(std::min(a, b), std::max(a, b));
  }
}

// A random member of x: an end (often) or a point inside.
double RandomPoint(std::mt19937_64& g, const Interval& x) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double r = u01(g);
  if (r < 0.2) return x.lo();
  if (r < 0.4) return x.hi();
  const LD t = u01(g);
  double v = static_cast<double>((1 - t) * static_cast<LD>(x.lo()) + t * static_cast<LD>(x.hi()));
  return std::min(std::max(v, x.lo()), x.hi());
}

// The double nearest to an extremum angle (phase + 2 pi k) inside x, if any
// (computed in long double; only for moderate magnitudes where that is exact
// enough).
bool ExtremumIn(const Interval& x, LD phase, double* at) {
  if (x.mag() > 1e9) return false;
  const LD k = std::ceil((static_cast<LD>(x.lo()) - phase) / (2 * kPiL));
  const double p = static_cast<double>(phase + 2 * kPiL * k);
  if (p < x.lo() || p > x.hi()) return false;
  *at = p;
  return true;
}

TEST(IntervalTest, RandomArithmeticEnclosesPointResults) {
  std::mt19937_64 g(0x5eed0001);
  Tally add, sub, mul, div, neg, sqr, sqrt;
  int64_t divisions_skipped = 0;
  constexpr int kCases = 200000;
  for (int c = 0; c < kCases; ++c) {
    const Interval X = RandomInterval(g);
    const Interval Y = RandomInterval(g);
    const Interval S = X + Y, D = X - Y, P = X * Y, N = -X, Q = Sqr(X), R = Sqrt(X);
    const bool y_has_zero = Y.lo() <= 0 && Y.hi() >= 0;
    const Interval V = X / Y;
    if (y_has_zero) {
      ++divisions_skipped;
      EXPECT_TRUE(V.lo() == -kInf && V.hi() == kInf) << Describe(X) << " / " << Describe(Y);
    }
    for (int k = 0; k < 4; ++k) {
      const double x = RandomPoint(g, X), y = RandomPoint(g, Y);
      const LD lx = x, ly = y;
      auto ctx_fn = [&] {
        return "X=" + Describe(X) + " Y=" + Describe(Y) + " x=" + Num(lx) + " y=" + Num(ly);
      };
      add.Check(Encloses(S, lx + ly), [&] { return "add " + ctx_fn() + " -> " + Describe(S); });
      sub.Check(Encloses(D, lx - ly), [&] { return "sub " + ctx_fn() + " -> " + Describe(D); });
      mul.Check(Encloses(P, lx * ly), [&] { return "mul " + ctx_fn() + " -> " + Describe(P); });
      neg.Check(Encloses(N, -lx), [&] { return "neg " + ctx_fn() + " -> " + Describe(N); });
      sqr.Check(Encloses(Q, lx * lx), [&] { return "sqr " + ctx_fn() + " -> " + Describe(Q); });
      if (x >= 0) {
        sqrt.Check(Encloses(R, std::sqrt(lx)),
                   [&] { return "sqrt " + ctx_fn() + " -> " + Describe(R); });
      }
      if (!y_has_zero) {
        div.Check(Encloses(V, lx / ly), [&] { return "div " + ctx_fn() + " -> " + Describe(V); });
      }
    }
  }
  for (const Tally* t : {&add, &sub, &mul, &div, &neg, &sqr, &sqrt}) {
    EXPECT_EQ(t->violations, 0) << t->first;
  }
  // The generator must exercise each operation a lot.
  EXPECT_GE(add.checks, 4 * kCases);
  EXPECT_GE(div.checks, kCases);
  EXPECT_GE(sqrt.checks, kCases);
  EXPECT_GT(divisions_skipped, 0);
}

TEST(IntervalTest, RandomSinCosEnclosePointResults) {
  std::mt19937_64 g(0x5eed0002);
  Tally sin_t, cos_t;
  int64_t extrema_checked = 0;
  constexpr int kCases = 150000;
  for (int c = 0; c < kCases; ++c) {
    const Interval X = RandomInterval(g);
    const Interval S = Sin(X), C = Cos(X);
    ASSERT_TRUE(S.lo() >= -1 && S.hi() <= 1 && S.is_valid()) << Describe(X) << Describe(S);
    ASSERT_TRUE(C.lo() >= -1 && C.hi() <= 1 && C.is_valid()) << Describe(X) << Describe(C);
    std::vector<double> points;
    for (int k = 0; k < 6; ++k) points.push_back(RandomPoint(g, X));
    // The doubles nearest to the extrema inside X: sin there is +-1 in long
    // double, so the result must reach +-1.
    for (LD phase : {kPiL / 2, -kPiL / 2, LD(0), kPiL}) {
      double at;
      if (ExtremumIn(X, phase, &at)) {
        points.push_back(at);
        ++extrema_checked;
      }
    }
    for (double x : points) {
      const LD lx = x;
      auto ctx_fn = [&] { return "X=" + Describe(X) + " x=" + Num(lx); };
      sin_t.Check(Encloses(S, std::sin(lx)), [&] {
        return "sin " + ctx_fn() + " sin=" + Num(std::sin(lx)) + " -> " + Describe(S);
      });
      cos_t.Check(Encloses(C, std::cos(lx)), [&] {
        return "cos " + ctx_fn() + " cos=" + Num(std::cos(lx)) + " -> " + Describe(C);
      });
    }
  }
  EXPECT_EQ(sin_t.violations, 0) << sin_t.first;
  EXPECT_EQ(cos_t.violations, 0) << cos_t.first;
  EXPECT_GE(sin_t.checks, 6 * kCases);
  EXPECT_GT(extrema_checked, 10000);
}

// Wide intervals that cross an extremum by a clear margin must reach +-1
// exactly; intervals of width >= 2 pi give exactly [-1, 1].
TEST(IntervalTest, SinCosReachExtremaOfWideIntervals) {
  std::mt19937_64 g(0x5eed0003);
  std::uniform_real_distribution<double> centre(-1000, 1000), width(0.01, 6.2);
  int64_t crossings = 0;
  for (int c = 0; c < 100000; ++c) {
    const double lo = centre(g);
    const Interval X(lo, lo + width(g));
    const Interval S = Sin(X), C = Cos(X);
    struct Case {
      const char* name;
      LD phase;
      const Interval* result;
      bool is_max;
    } cases[] = {{"sin max", kPiL / 2, &S, true},
                 {"sin min", -kPiL / 2, &S, false},
                 {"cos max", 0, &C, true},
                 {"cos min", kPiL, &C, false}};
    for (const Case& k : cases) {
      const LD n = std::ceil((static_cast<LD>(X.lo()) - k.phase) / (2 * kPiL));
      const LD p = k.phase + 2 * kPiL * n;
      if (p > X.lo() + 1e-9L && p < X.hi() - 1e-9L) {
        ++crossings;
        if (k.is_max) {
          EXPECT_EQ(k.result->hi(), 1.0) << k.name << " X=" << Describe(X);
        } else {
          EXPECT_EQ(k.result->lo(), -1.0) << k.name << " X=" << Describe(X);
        }
      }
    }
  }
  EXPECT_GT(crossings, 50000);
  for (double lo : {-1e6, -7.0, -3.0, 0.0, 1e-300, 2.5, 1e3, 1e15, 1e300}) {
    for (double w : {2 * kPiD, 2 * kPiD + 1e-9, 7.0, 100.0, 1e20}) {
      const Interval X(lo, lo + w);
      if (!(X.width() >= 2 * kPiD)) continue;
      EXPECT_EQ(Sin(X).lo(), -1.0) << Describe(X);
      EXPECT_EQ(Sin(X).hi(), 1.0) << Describe(X);
      EXPECT_EQ(Cos(X).lo(), -1.0) << Describe(X);
      EXPECT_EQ(Cos(X).hi(), 1.0) << Describe(X);
    }
  }
  EXPECT_EQ(Sin(Interval::Everything()).lo(), -1.0);
  EXPECT_EQ(Cos(Interval::Everything()).hi(), 1.0);
}

// Narrow intervals (a few ulps) give narrow results: the enclosure is not
// bought by answering [-1, 1] everywhere.
TEST(IntervalTest, SinCosOfNarrowIntervalsAreNarrow) {
  std::mt19937_64 g(0x5eed0004);
  std::uniform_real_distribution<double> x(-100, 100);
  for (int c = 0; c < 20000; ++c) {
    const double v = x(g);
    const Interval X(v, std::nextafter(std::nextafter(v, kInf), kInf));
    EXPECT_LT(Sin(X).width(), 1e-12) << Describe(X);
    EXPECT_LT(Cos(X).width(), 1e-12) << Describe(X);
    EXPECT_TRUE(Encloses(Sin(X), std::sin(static_cast<LD>(v)))) << Describe(X);
    EXPECT_TRUE(Encloses(Cos(X), std::cos(static_cast<LD>(v)))) << Describe(X);
  }
}

// Regression: Cos(x) is computed as Sin(x + pi/2), and the double kPi / 2 is
// 6.1e-17 below the real pi/2 (and kPi/2 +- 1e-16 rounds back to kPi/2, so the
// "guard" in interval.cc is empty). Near x = -pi/2 the sum is tiny, its one-ulp
// widening cannot cover 6.1e-17, and the result misses cos(x) = 6.12e-17.
TEST(IntervalTest, CosNearMinusHalfPiEnclosesTrueValue) {
  const double x = -kPiD / 2;
  const LD exact = std::cos(static_cast<LD>(x));  // 6.123e-17
  EXPECT_TRUE(Encloses(Cos(Interval(x)), exact))
      << "cos(" << Num(x) << ") = " << Num(exact) << " not in " << Describe(Cos(Interval(x)));
  EXPECT_TRUE(Encloses(Cos(Interval(x, x + 1e-20)), exact));
}

TEST(IntervalTest, OutwardIsStrictlyWider) {
  std::mt19937_64 g(0x5eed0005);
  for (int c = 0; c < 100000; ++c) {
    const Interval X = RandomInterval(g);
    const int ulps = std::uniform_int_distribution<int>(1, 8)(g);
    const Interval W = Interval::Outward(X.lo(), X.hi(), ulps);
    EXPECT_LT(W.lo(), X.lo()) << Describe(X) << " ulps=" << ulps;
    EXPECT_GT(W.hi(), X.hi()) << Describe(X) << " ulps=" << ulps;
    // Exactly `ulps` representable steps, no more.
    double lo = X.lo(), hi = X.hi();
    for (int k = 0; k < ulps; ++k) {
      lo = std::nextafter(lo, -kInf);
      hi = std::nextafter(hi, kInf);
    }
    EXPECT_EQ(W.lo(), lo);
    EXPECT_EQ(W.hi(), hi);
  }
  // The ends of the double range widen to infinity.
  const double big = std::numeric_limits<double>::max();
  const Interval W = Interval::Outward(-big, big, 1);
  EXPECT_EQ(W.lo(), -kInf);
  EXPECT_EQ(W.hi(), kInf);
  // Zero widens to the smallest subnormals.
  const Interval Z = Interval::Outward(0, 0, 1);
  EXPECT_LT(Z.lo(), 0.0);
  EXPECT_GT(Z.hi(), 0.0);
}

// The arithmetic results are outward rounded: strictly wider than the
// round-to-nearest hull of the end combinations.
TEST(IntervalTest, ArithmeticIsStrictlyOutward) {
  std::mt19937_64 g(0x5eed0006);
  std::uniform_real_distribution<double> v(-1e6, 1e6);
  for (int c = 0; c < 20000; ++c) {
    const double a = v(g), b = v(g), x = v(g), y = v(g);
    const Interval A(std::min(a, b), std::max(a, b)), B(std::min(x, y), std::max(x, y));
    EXPECT_LT((A + B).lo(), A.lo() + B.lo());
    EXPECT_GT((A + B).hi(), A.hi() + B.hi());
    EXPECT_LT((A - B).lo(), A.lo() - B.hi());
    EXPECT_GT((A - B).hi(), A.hi() - B.lo());
    const double p[4] = {A.lo() * B.lo(), A.lo() * B.hi(), A.hi() * B.lo(), A.hi() * B.hi()};
    EXPECT_LT((A * B).lo(), *std::min_element(p, p + 4));
    EXPECT_GT((A * B).hi(), *std::max_element(p, p + 4));
  }
}

// NormUpper is the upper end of the interval norm of a point, bit for bit:
// its brute-force twin is the full interval expression it replaces.
TEST(IntervalTest, NormUpperEqualsIntervalNormBitForBit) {
  std::mt19937_64 g(20261124);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double specials[] = {0.0, -0.0, 1.0, -1.0, std::numeric_limits<double>::denorm_min(),
                             std::numeric_limits<double>::min(), 1e-160, 1e154, 1e155,
                             std::numeric_limits<double>::max(), kInf, -kInf,
                             std::numeric_limits<double>::quiet_NaN()};
  auto pick = [&]() {
    const double r = u01(g);
    if (r < 0.15) return specials[std::uniform_int_distribution<int>(0, 12)(g)];
    if (r < 0.5) return std::uniform_real_distribution<double>(-3, 3)(g);  // Avatars' metres.
    return RandomValue(g);
  };
  int64_t checks = 0;
  for (int k = 0; k < 2'000'000; ++k) {
    const double x = pick(), y = pick(), z = pick();
    const Interval full = Sqrt(Sqr(Interval(x)) + Sqr(Interval(y)) + Sqr(Interval(z)));
    const double upper = NormUpper(x, y, z);
    const double want = full.hi();
    ASSERT_EQ(Bits(upper), Bits(want)) << "x " << Num(x) << " y " << Num(y) << " z " << Num(z) << ": " << Num(upper)
                    << " vs " << Num(want);
    ++checks;
  }
  EXPECT_EQ(checks, 2'000'000);
}

// The larger of two NormUppers from one square root (NormUpperOfSum of the
// larger SumOfSquaresUpper): its twin is the larger of the two NormUppers,
// bit for bit, on finite coordinates from subnormal to overflowing squares.
TEST(IntervalTest, LargerNormFromTheLargerSumBitForBit) {
  std::mt19937_64 g(0x4a11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto pick = [&]() {
    const double r = u01(g);
    if (r < 0.05) return 0.0;
    if (r < 0.5) return std::uniform_real_distribution<double>(-3, 3)(g);
    return RandomValue(g);
  };
  for (int k = 0; k < 1'000'000; ++k) {
    const double x0 = pick(), y0 = pick(), z0 = pick();
    double x1 = pick(), y1 = pick(), z1 = pick();
    if (u01(g) < 0.1) x1 = x0, y1 = y0, z1 = std::nextafter(z0, kInf);  // Near ties.
    if (!std::isfinite(x1) || !std::isfinite(y1) || !std::isfinite(z1)) continue;
    const double want = std::max(NormUpper(x0, y0, z0), NormUpper(x1, y1, z1));
    const double got = NormUpperOfSum(
        std::max(SumOfSquaresUpper(x0, y0, z0), SumOfSquaresUpper(x1, y1, z1)));
    ASSERT_EQ(Bits(got), Bits(want)) << k << ": " << Num(got) << " vs " << Num(want);
  }
}

// operator* takes a shortcut for valid, finite, non-negative operands; its
// brute-force twin is the general rule (Outward of the least and greatest of
// the four end products), compared bit for bit.
TEST(IntervalTest, ProductShortcutEqualsFourProductRuleBitForBit) {
  std::mt19937_64 g(0x9e0d);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double specials[] = {0.0, -0.0, 1.0, std::numeric_limits<double>::denorm_min(),
                             std::numeric_limits<double>::min(), 1e-160, 1e154, 1e155,
                             std::numeric_limits<double>::max(), kInf};
  auto pick = [&]() {
    const double r = u01(g);
    if (r < 0.2) return specials[std::uniform_int_distribution<int>(0, 9)(g)];
    if (r < 0.6) return std::fabs(RandomValue(g));
    return RandomValue(g);
  };
  for (int k = 0; k < 2'000'000; ++k) {
    double a0 = pick(), a1 = pick(), b0 = pick(), b1 = pick();
    if (u01(g) < 0.9) {  // Mostly valid intervals; some inverted ones too.
      if (a1 < a0) std::swap(a0, a1);
      if (b1 < b0) std::swap(b0, b1);
    }
    if (u01(g) < 0.1) a1 = a0;
    const Interval A(a0, a1), B(b0, b1);
    const double p[4] = {a0 * b0, a0 * b1, a1 * b0, a1 * b1};
    const Interval want =
        Interval::Outward(*std::min_element(p, p + 4), *std::max_element(p, p + 4), 1);
    const Interval got = A * B;
    ASSERT_EQ(Bits(got.lo()), Bits(want.lo())) << Describe(A) << " * " << Describe(B);
    ASSERT_EQ(Bits(got.hi()), Bits(want.hi())) << Describe(A) << " * " << Describe(B);
  }
}

TEST(IntervalTest, SmallHelpers) {
  const Interval X(-2, 3);
  EXPECT_EQ(X.width(), 5);
  EXPECT_EQ(X.mid(), 0.5);
  EXPECT_EQ(X.mag(), 3);
  EXPECT_TRUE(X.contains(-2));
  EXPECT_TRUE(X.contains(3));
  EXPECT_FALSE(X.contains(3.0000001));
  EXPECT_EQ(X.ClampLow0().lo(), 0);
  EXPECT_EQ(Interval(1, 2).ClampLow0().lo(), 1);
  EXPECT_FALSE(Interval(2, 1).is_valid());
  const Interval H = Interval::Hull(Interval(1, 2), Interval(-5, -4));
  EXPECT_EQ(H.lo(), -5);
  EXPECT_EQ(H.hi(), 2);
  EXPECT_EQ((-X).lo(), -3);
  EXPECT_EQ((-X).hi(), 2);
  // Sqr of an interval straddling 0 starts at exactly 0; x*x does not.
  EXPECT_EQ(Sqr(X).lo(), 0);
  EXPECT_LT((X * X).lo(), 0);
  EXPECT_GE(Sqr(X).hi(), 9);
  // Sqrt of a partly negative interval uses its non-negative part.
  EXPECT_EQ(Sqrt(Interval(-4, 4)).lo(), 0);
  EXPECT_GE(Sqrt(Interval(-4, 4)).hi(), 2);
  Interval acc(1);
  acc += Interval(2);
  EXPECT_TRUE(acc.contains(3));
  acc *= Interval(2);
  EXPECT_TRUE(acc.contains(6));
}

}  // namespace
}  // namespace sweptccd
