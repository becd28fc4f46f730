#pragma once
// Outward-rounded interval arithmetic on doubles.
//
// Every operation computes the result in round-to-nearest and then widens it
// by one unit in the last place on each side (std::nextafter). Round-to-nearest
// is within half an ulp of the exact result, so the widened interval encloses
// the exact result of the operation on any real numbers in the operands. The
// elementary functions (sqrt, sin, cos, atan2) of glibc are accurate to a few
// ulps; those widen by kLibmUlps on each side.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace sweptccd {

class Interval {
 public:
  static constexpr int kLibmUlps = 4;
  static constexpr double kFiniteMax = std::numeric_limits<double>::max();

  constexpr Interval() = default;
  constexpr Interval(double v) : lo_(v), hi_(v) {}  // NOLINT: implicit by design
  constexpr Interval(double lo, double hi) : lo_(lo), hi_(hi) {}

  double lo() const { return lo_; }
  double hi() const { return hi_; }
  double width() const { return hi_ - lo_; }
  double mid() const { return 0.5 * (lo_ + hi_); }
  /// Largest absolute value of a member.
  double mag() const { return std::max(std::fabs(lo_), std::fabs(hi_)); }
  bool contains(double v) const { return lo_ <= v && v <= hi_; }
  bool is_valid() const { return lo_ <= hi_; }
  /// The same interval with its lower end raised to 0 (for squares and norms).
  Interval ClampLow0() const { return Interval(std::max(0.0, lo_), hi_); }

  friend Interval operator+(const Interval& a, const Interval& b) {
    return Outward(a.lo_ + b.lo_, a.hi_ + b.hi_, 1);
  }
  friend Interval operator-(const Interval& a, const Interval& b) {
    return Outward(a.lo_ - b.hi_, a.hi_ - b.lo_, 1);
  }
  friend Interval operator-(const Interval& a) { return Interval(-a.hi_, -a.lo_); }
  friend Interval operator*(const Interval& a, const Interval& b) {
    // Both operands valid, finite and non-negative (the motion's bounds,
    // nearly every product): rounded multiplication is monotone there, so the
    // extreme products are lo * lo and hi * hi. The same bits as the four
    // products below: ties can only differ in the sign of a zero, and
    // Outward widens -0 and +0 alike.
    if (0 <= a.lo_ && a.lo_ <= a.hi_ && a.hi_ <= kFiniteMax && 0 <= b.lo_ && b.lo_ <= b.hi_ &&
        b.hi_ <= kFiniteMax) {
      return Outward(a.lo_ * b.lo_, a.hi_ * b.hi_, 1);
    }
    const double p[4] = {a.lo_ * b.lo_, a.lo_ * b.hi_, a.hi_ * b.lo_, a.hi_ * b.hi_};
    return Outward(*std::min_element(p, p + 4), *std::max_element(p, p + 4), 1);
  }
  /// Division; the divisor must not contain zero (else the result is everything).
  friend Interval operator/(const Interval& a, const Interval& b) {
    if (b.lo_ <= 0 && b.hi_ >= 0) return Everything();
    const double p[4] = {a.lo_ / b.lo_, a.lo_ / b.hi_, a.hi_ / b.lo_, a.hi_ / b.hi_};
    return Outward(*std::min_element(p, p + 4), *std::max_element(p, p + 4), 1);
  }
  Interval& operator+=(const Interval& o) { return *this = *this + o; }
  Interval& operator*=(const Interval& o) { return *this = *this * o; }

  static Interval Everything() {
    return Interval(-std::numeric_limits<double>::infinity(),
                    std::numeric_limits<double>::infinity());
  }
  /// Hull of two intervals.
  static Interval Hull(const Interval& a, const Interval& b) {
    return Interval(std::min(a.lo_, b.lo_), std::max(a.hi_, b.hi_));
  }

  /// Widens [lo, hi] by `ulps` units in the last place on each side.
  static Interval Outward(double lo, double hi, int ulps) {
    return Interval(-StepUp(-lo, ulps), StepUp(hi, ulps));
  }

  /// NextUp applied `ulps` times (ulps >= 0), bit for bit: for a finite x
  /// at least `ulps` steps from zero and from infinity, one integer step.
  static double StepUp(double x, int ulps) {
    uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const uint64_t magnitude = bits & ~(uint64_t{1} << 63);
    const uint64_t k = static_cast<uint64_t>(ulps);
    constexpr uint64_t kInfBits = uint64_t{0x7ff} << 52;
    if (magnitude > k && magnitude < kInfBits - k) {
      bits = (bits >> 63) == 0 ? bits + k : bits - k;
      std::memcpy(&x, &bits, sizeof bits);
      return x;
    }
    for (int i = 0; i < ulps; ++i) x = NextUp(x);
    return x;
  }

  /// std::nextafter(x, +inf), bit for bit (NaN, zeros, infinities and
  /// subnormals included), inline: the out-of-line libm call was a quarter of
  /// a culled pair's time (every interval operation rounds twice).
  static double NextUp(double x) {
    if (x != x || x == std::numeric_limits<double>::infinity()) return x;
    if (x == 0) return std::numeric_limits<double>::denorm_min();
    uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    bits = x > 0 ? bits + 1 : bits - 1;
    std::memcpy(&x, &bits, sizeof bits);
    return x;
  }
  /// std::nextafter(x, -inf), bit for bit.
  static double NextDown(double x) { return -NextUp(-x); }

 private:
  double lo_ = 0;
  double hi_ = 0;
};

/// x^2 (tighter than x * x when x straddles zero).
inline Interval Sqr(const Interval& x) {
  const double a = x.lo() * x.lo(), b = x.hi() * x.hi();
  if (x.lo() <= 0 && x.hi() >= 0) return Interval::Outward(0, std::max(a, b), 1).ClampLow0();
  return Interval::Outward(std::min(a, b), std::max(a, b), 1);
}

/// sqrt of the non-negative part of x.
inline Interval Sqrt(const Interval& x) {
  const double lo = std::max(0.0, x.lo()), hi = std::max(0.0, x.hi());
  Interval r = Interval::Outward(std::sqrt(lo), std::sqrt(hi), Interval::kLibmUlps);
  return Interval(std::max(0.0, r.lo()), r.hi());
}

/// Sqrt(Sqr(x) + Sqr(y) + Sqr(z)).hi() for points x, y, z, bit for bit (the
/// same roundings of the upper ends), without the lower ends: the motion's
/// bounds only ever read the upper end of a norm. Each Sqr's upper end is
/// x * x stepped up once (for x = 0 too: Sqr clamps the lower end only).
/// NormUpper's two steps: the rounded-up sum of squares, then its rounded-up
/// square root. Both are nondecreasing, so the larger of two NormUppers is
/// NormUpperOfSum of the larger sum (one square root instead of two).
inline double SumOfSquaresUpper(double x, double y, double z) {
  return Interval::StepUp(
      Interval::StepUp(Interval::StepUp(x * x, 1) + Interval::StepUp(y * y, 1), 1) +
          Interval::StepUp(z * z, 1),
      1);
}
inline double NormUpperOfSum(double sum) {
  return Interval::StepUp(std::sqrt(std::max(0.0, sum)), Interval::kLibmUlps);
}

inline double NormUpper(double x, double y, double z) {
  return NormUpperOfSum(SumOfSquaresUpper(x, y, z));
}

/// sin over an interval, using monotone pieces between the extrema.
Interval Sin(const Interval& x);
/// cos over an interval.
Interval Cos(const Interval& x);

}  // namespace sweptccd
