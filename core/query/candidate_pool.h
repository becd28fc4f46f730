#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): the
// candidate pool, one query's store of the primitives that can still touch
// each open time interval. An interval keeps its candidates as a range of the
// pool; its halves filter that range into new ranges, so the lists shrink as
// the intervals do.

#include <cstdint>
#include <vector>

#include "core/query/environment_target.h"
#include "core/query/link_capsule.h"

namespace sweptccd::internal {

/// An interval's candidates: `count` pool entries from `begin`, or, when
/// `requery`, too many to list (count is then 1: "not empty") and the target
/// is asked afresh.
struct CandidateList {
  uint32_t begin = 0;
  uint32_t count = 0;
  bool requery = false;
};

/// Append-only during a query (ranges stay valid). Single-threaded: one per
/// query run. Counts every triangle test in *triangle_tests.
class CandidatePool {
 public:
  CandidatePool(const EnvironmentTarget& target, int max_candidates, int64_t* triangle_tests);

  /// Starts the pool in `storage`'s array (emptied; its capacity kept), so a
  /// query can reuse an earlier one's; Release gives it back.
  void Adopt(std::vector<Candidate>&& storage) {
    entries_ = std::move(storage);
    entries_.clear();
  }
  std::vector<Candidate> Release() { return std::move(entries_); }

  /// Appends every unfiltered primitive within the capsule (of capsule.link),
  /// found through the target's BVHs: all objects, or only `object` from BVH
  /// node `start_node` when object is valid. Returns false, appending
  /// nothing, past max_candidates.
  bool CollectFromBvh(const LinkCapsule& capsule, ObjectIndex object = ObjectIndex(),
                      uint32_t start_node = 0);

  /// Whether some unfiltered primitive of `object` below BVH node
  /// `start_node` is within the capsule (the test CollectFromBvh applies),
  /// stopping at the first.
  bool AnyWithin(const LinkCapsule& capsule, ObjectIndex object, uint32_t start_node);
  /// As AnyWithin, giving up after `budget` primitive tests (negative: no
  /// limit): kFound, kNone, or kUndecided (the budget ran out first).
  enum class Search { kFound, kNone, kUndecided };
  Search AnyWithinBudget(const LinkCapsule& capsule, ObjectIndex object, uint32_t start_node,
                         int budget);

  /// The candidates of a child interval whose capsule is `capsule`, from its
  /// parent's list: the parent's entries within the capsule, or the target's
  /// when the parent had none listed (requery).
  CandidateList Refine(const CandidateList& parent, const LinkCapsule& capsule);

  /// The exact nearest of the list's candidates to capsule.link at s.
  bool Nearest(const PairMotion& motion, LinkIndex link, double s, const CandidateList& list,
               ContactRecord* best);

  size_t size() const { return entries_.size(); }
  /// Every entry in order, the lists' ranges index into it.
  const std::vector<Candidate>& entries() const { return entries_; }
  int max_candidates() const { return max_candidates_; }

 private:
  void ReserveOnFirstUse();
  bool Within(const LinkCapsule& capsule, Candidate candidate) {
    ++*triangle_tests_;
    return target_.WithinCapsule(capsule, candidate);
  }
  // Within, for a candidate the BVH query with this capsule just passed.
  bool WithinFromQuery(const LinkCapsule& capsule, Candidate candidate) {
    ++*triangle_tests_;
    return target_.WithinCapsuleFromQuery(capsule, candidate);
  }

  const EnvironmentTarget& target_;
  int max_candidates_;
  int64_t* triangle_tests_;
  std::vector<Candidate> entries_;
};

}  // namespace sweptccd::internal
