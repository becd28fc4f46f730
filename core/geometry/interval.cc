#include "core/geometry/interval.h"

#include <cmath>

namespace sweptccd {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

Interval Sin(const Interval& x) {
  if (!(x.width() < 2 * kPi) || !std::isfinite(x.lo()) || !std::isfinite(x.hi())) {
    return Interval(-1, 1);
  }
  // sin has maxima at pi/2 + 2k pi and minima at -pi/2 + 2k pi. Check whether
  // one lies in x; the guard band of 1e-12 rad absorbs the rounding of the
  // k computations (it only widens the answer).
  // The guard must grow with |x|: 2 pi k is off by ~1e-16 |x|.
  const double guard = 1e-12 * std::max(1.0, x.mag());
  auto contains_point = [&](double phase) {
    const double k = std::ceil((x.lo() - phase - guard) / (2 * kPi));
    const double p = phase + 2 * kPi * k;
    return p <= x.hi() + guard;
  };
  const double s0 = std::sin(x.lo()), s1 = std::sin(x.hi());
  double lo = std::min(s0, s1), hi = std::max(s0, s1);
  Interval r = Interval::Outward(lo, hi, Interval::kLibmUlps);
  lo = r.lo();
  hi = r.hi();
  if (contains_point(kPi / 2)) hi = 1;
  if (contains_point(-kPi / 2)) lo = -1;
  return Interval(std::max(-1.0, lo), std::min(1.0, hi));
}

// cos(x) = sin(x + pi/2). The double kPi / 2 is 6.1e-17 below pi/2, so the
// shift interval must reach the next double up to contain the true pi/2.
Interval Cos(const Interval& x) { return Sin(x + Interval(kPi / 2, std::nextafter(kPi / 2, 4.0))); }

}  // namespace sweptccd
