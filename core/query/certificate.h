#pragma once
// The rules of the certificate (SPEC 6) that close an item of a descent,
// written once for both engines: the static environment's (core/query,
// QueryRun) and the shared world's (core/world, EntityRun). Each engine has
// its own queue and time variable (s or tau); the rules are the same.
//
// G3, a narrow item closes: the nearest of its samples is within delta,
// with the rounding slack as margin (AcceptedSeparation).
// Out of work (G1 kept): every link with work left is undecided from the
// earliest start among its open items (OpenWork).

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/typed_index.h"

namespace sweptccd {

/// The largest separation at which a narrow item closes: delta less the
/// slack `tol_m`, so that a checker reading the files' decimal coordinates
/// (the engine holds floats) still sees <= delta; when delta is within a
/// few slacks, plain delta (termination).
inline double AcceptedSeparation(double delta_m, double tol_m) {
  return delta_m > 4 * tol_m ? delta_m - tol_m : delta_m;
}

/// The work left when the work limit is reached: per link, the earliest
/// start among the items still open. Single-use.
class OpenWork {
 public:
  explicit OpenWork(int num_links) : earliest_(static_cast<size_t>(num_links), HUGE_VAL) {}
  /// An open item of `link` starting at `start`.
  void Note(int link, double start) {
    double& e = earliest_[static_cast<size_t>(link)];
    e = std::min(e, start);
  }
  /// Whether `link` has work left (some item was noted).
  bool open(int link) const { return earliest_[static_cast<size_t>(link)] != HUGE_VAL; }
  /// Where its undecided bracket starts. Precondition: open(link).
  double earliest(int link) const { return earliest_[static_cast<size_t>(link)]; }
  /// The links with work left, earliest first (ties: std::sort's order
  /// over the links in index order).
  std::vector<LinkIndex> ByEarliest() const {
    std::vector<LinkIndex> order;
    for (LinkIndex l(0); l < static_cast<int>(earliest_.size()); ++l) {
      if (open(l)) order.push_back(l);
    }
    std::sort(order.begin(), order.end(),
              [&](LinkIndex x, LinkIndex y) { return earliest(x) < earliest(y); });
    return order;
  }

 private:
  std::vector<double> earliest_;
};

}  // namespace sweptccd
