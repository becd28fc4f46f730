#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): the
// brackets and witnesses a query answers with. A link is closed once, by a
// leaf (a narrow interval with a witness), or undecided (no split left, or
// out of work); assembly picks the earliest bracket over all links.

#include <vector>

#include "core/query/ccd_query.h"
#include "core/query/environment_target.h"

namespace sweptccd::internal {

/// One query's closed links. Single-threaded, one per query.
class Witnesses {
 public:
  Witnesses(const EnvironmentTarget& target, const PairMotion& motion, int num_links)
      : target_(target), motion_(motion), done_(num_links, false) {}

  /// Links known clear of the environment over the whole pair (their link
  /// group's ball met nothing; null: none): they never touch at s = 0, and
  /// their poses, which may not be composed, are not asked for.
  void SetClearForPair(const std::vector<char>* clear) { clear_for_pair_ = clear; }

  /// Whether the link is closed (it needs no more work).
  bool done(LinkIndex link) const { return done_[link]; }
  const std::vector<bool>& done() const { return done_; }
  bool empty() const { return brackets_.empty(); }

  /// Closes `link` with [s0, s1] and `witness`. Unless `exact_witness`, the
  /// witness (nearest among the interval's candidates) is replaced by the
  /// exact nearest at its s when that is nearer.
  void CloseLeaf(LinkIndex link, double s0, double s1, const ContactRecord& witness,
                 bool exact_witness = false);
  /// Closes `link` as undecided from s_lo, with the nearest triangle at s_lo
  /// as a best-effort witness.
  void CloseUndecided(LinkIndex link, double s_lo);

  /// The answer: the earliest bracket, the witnesses of other links inside it
  /// (within delta), and initially_colliding. Keeps `links` in per-link mode.
  /// Consumes the brackets.
  QueryResult Assemble(const QueryOptions& options, QueryResult result);

 private:
  bool InitiallyTouching(LinkIndex link) const {
    if (clear_for_pair_ != nullptr && (*clear_for_pair_)[link] != 0) return false;
    return target_.TouchesAt(motion_, link, 0.0, 0.0);
  }

  const EnvironmentTarget& target_;
  const PairMotion& motion_;
  std::vector<bool> done_;
  std::vector<LinkBracket> brackets_;
  const std::vector<char>* clear_for_pair_ = nullptr;
};

}  // namespace sweptccd::internal
