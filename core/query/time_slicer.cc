#include "core/query/time_slicer.h"

#include "core/query/ccd_query.h"

namespace sweptccd::internal {

TimeSlicer::TimeSlicer(int64_t utime0, int64_t utime1, double eps_s)
    : utime0_(utime0),
      utime1_(utime1),
      dt_us_(PairDurationUs(utime0, utime1)),
      eps_us_(eps_s * 1e6) {}

bool TimeSlicer::Narrow(double s0, double s1) const {
  const double t_lo = BracketTimeLo(utime0_, utime1_, s0);
  const double t_hi = BracketTimeHi(utime0_, utime1_, s1);
  return (s1 - s0) * dt_us_ <= eps_us_ && t_hi - t_lo <= eps_us_;
}

double TimeSlicer::FirstNarrowWidth() const {
  double w = 1;
  while (w > 1e-300 && !Narrow(0, w)) w *= 0.5;
  return w;
}

bool TimeSlicer::Split(const Interval& parent, const LinkCapsule& mid_capsule,
                       const CandidateList& list, Interval* lower, Interval* upper) {
  const double mid = 0.5 * (parent.s0 + parent.s1);
  if (!(mid > parent.s0 && mid < parent.s1) || parent.depth >= 400) return false;
  *lower = Interval{parent.s0, mid, parent.link, parent.depth + 1, list, false, parent.ends};
  *upper = Interval{mid, parent.s1, parent.link, parent.depth + 1, list, false, parent.ends};
  lower->ends.a1 = upper->ends.a0 = mid_capsule.a;
  lower->ends.b1 = upper->ends.b0 = mid_capsule.b;
  return true;
}

}  // namespace sweptccd::internal
