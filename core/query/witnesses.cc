#include "core/query/witnesses.h"

#include <algorithm>
#include <limits>

namespace sweptccd::internal {

void Witnesses::CloseLeaf(LinkIndex link, double s0, double s1, const ContactRecord& witness,
                          bool exact_witness) {
  LinkBracket bracket;
  bracket.link = link;
  bracket.s_lo = s0;
  bracket.s_hi = s1;
  bracket.has_witness = true;
  bracket.witness = witness;
  // The candidates hold every triangle that can touch; one outside them can
  // still be the nearest when nothing touches. Make the witness exact.
  ContactRecord exact;
  if (!exact_witness && target_.Separation(motion_, link, witness.s, witness.separation, &exact) &&
      exact.separation < witness.separation) {
    bracket.witness = exact;
  }
  bracket.initially_colliding =
      s0 == 0 &&
      ((bracket.witness.s == 0 && bracket.witness.separation <= 0) || InitiallyTouching(link));
  brackets_.push_back(bracket);
  done_[link] = true;
}

void Witnesses::CloseUndecided(LinkIndex link, double s_lo) {
  LinkBracket bracket;
  bracket.link = link;
  bracket.s_lo = s_lo;
  bracket.s_hi = 1;
  bracket.undecided = true;
  ContactRecord r;
  // Best effort: the nearest triangle at s_lo (any distance).
  if (target_.Separation(motion_, link, s_lo, std::numeric_limits<double>::infinity(), &r)) {
    bracket.has_witness = true;
    bracket.witness = r;
  }
  bracket.initially_colliding = s_lo == 0 && InitiallyTouching(link);
  brackets_.push_back(bracket);
  done_[link] = true;
}

QueryResult Witnesses::Assemble(const QueryOptions& options, QueryResult result) {
  result.links = std::move(brackets_);
  std::sort(result.links.begin(), result.links.end(),
            [](const LinkBracket& x, const LinkBracket& y) { return x.link < y.link; });
  const LinkBracket* first = nullptr;
  for (const LinkBracket& b : result.links) {
    if (first == nullptr || b.s_lo < first->s_lo) first = &b;
  }
  if (first != nullptr) {
    result.contact = true;
    result.s_lo = first->s_lo;
    result.s_hi = first->s_hi;
    result.undecided = first->undecided;
    if (first->has_witness) result.contacts.push_back(first->witness);
    // Other links' witnesses that fall inside the same bracket.
    for (const LinkBracket& b : result.links) {
      if (&b != first && b.has_witness && b.witness.s >= result.s_lo &&
          b.witness.s <= result.s_hi && b.witness.separation <= options.delta_m) {
        result.contacts.push_back(b.witness);
      }
    }
    for (const LinkBracket& b : result.links) {
      result.initially_colliding = result.initially_colliding || b.initially_colliding;
    }
    const int n = static_cast<int>(done_.size());
    if (result.s_lo == 0) {
      for (LinkIndex l(0); l < n && !result.initially_colliding; ++l) {
        if (!target_.IgnoresAll(l) && InitiallyTouching(l)) result.initially_colliding = true;
      }
    }
  }
  if (!options.per_link) result.links.clear();
  return result;
}

}  // namespace sweptccd::internal
