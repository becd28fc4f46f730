#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): time
// slicing. Each link's pair [0, 1] is halved into intervals, visited in
// chronological order, until an interval is cleared (no candidate within its
// swept capsule) or narrow enough (G2) to close with a witness (G3).

#include <cstdint>
#include <queue>
#include <vector>

#include "core/query/candidate_pool.h"
#include "core/query/swept_bounds.h"

namespace sweptccd::internal {

/// A time interval of one link still to be cleared.
struct Interval {
  double s0 = 0, s1 = 1;
  LinkIndex link;
  int depth = 0;
  CandidateList candidates;  // The parent's (or, when prefiltered, its own).
  bool prefiltered = false;  // The list was built for exactly this interval.
  SegmentEnds ends;          // The link's segment at s0 and s1.
};

/// Earliest first; ties by link index.
struct IntervalLater {
  bool operator()(const Interval& x, const Interval& y) const {
    if (x.s0 != y.s0) return x.s0 > y.s0;
    return x.link > y.link;
  }
};

/// The chronological queue, with its pending intervals readable (cull
/// batching asks about them ahead of the descent).
class IntervalQueue : public std::priority_queue<Interval, std::vector<Interval>, IntervalLater> {
 public:
  const std::vector<Interval>& pending() const { return c; }
  /// Starts empty in `storage`'s array (its capacity kept); Release gives
  /// it back. The order of the intervals does not depend on the capacity.
  void Adopt(std::vector<Interval>&& storage) {
    c = std::move(storage);
    c.clear();
  }
  std::vector<Interval> Release() { return std::move(c); }
};

/// The pair's time: when an interval is narrow enough (G2), and where it
/// splits. Plain values; thread-compatible.
class TimeSlicer {
 public:
  TimeSlicer(int64_t utime0, int64_t utime1, double eps_s);

  /// G2 in both readings: the width in s times the pair's duration, and the
  /// difference of the printed times (which rounds at epoch-size utimes).
  bool Narrow(double s0, double s1) const;
  /// The first dyadic width w with [0, w] narrow: the interval the
  /// chronological descent would reach at s = 0.
  double FirstNarrowWidth() const;

  /// The two halves of `parent`, each with `list` as its candidates;
  /// `mid_capsule` is the parent's capsule (its segment is the link's
  /// segment at the midpoint). False when the interval cannot be split
  /// (the midpoint rounds to an end, or it is 400 levels deep).
  static bool Split(const Interval& parent, const LinkCapsule& mid_capsule,
                    const CandidateList& list, Interval* lower, Interval* upper);

 private:
  int64_t utime0_, utime1_;
  double dt_us_, eps_us_;
};

}  // namespace sweptccd::internal
