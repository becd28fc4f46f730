#include "core/query/candidate_pool.h"

namespace sweptccd::internal {

CandidatePool::CandidatePool(const EnvironmentTarget& target, int max_candidates,
                             int64_t* triangle_tests)
    : target_(target), max_candidates_(max_candidates), triangle_tests_(triangle_tests) {}

void CandidatePool::ReserveOnFirstUse() {
  // Most pairs list nothing (every link culled): no 8 KiB allocation for them.
  if (entries_.capacity() == 0) entries_.reserve(1024);
}

bool CandidatePool::CollectFromBvh(const LinkCapsule& cap, ObjectIndex object,
                                   uint32_t start_node) {
  ReserveOnFirstUse();
  const size_t start = entries_.size();
  bool overflow = false;
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    if ((object.is_valid() && o != object) || target_.Ignores(cap.link, o)) continue;
    double radius = cap.radius;
    target_.bvh(o).QueryCapsuleShrinking(
        cap.a, cap.b, &radius,
        [&](uint32_t slot) {
          const Candidate c{static_cast<uint32_t>(o.value()), slot};
          if (!WithinFromQuery(cap, c)) return true;
          entries_.push_back(c);
          // Past the cap the list is not worth keeping: stop early.
          overflow = entries_.size() - start > static_cast<size_t>(max_candidates_);
          return !overflow;
        },
        object.is_valid() ? start_node : 0);
    if (overflow) break;
  }
  if (overflow) entries_.resize(start);
  return !overflow;
}

bool CandidatePool::AnyWithin(const LinkCapsule& cap, ObjectIndex object, uint32_t start_node) {
  return AnyWithinBudget(cap, object, start_node, /*budget=*/-1) == Search::kFound;
}

CandidatePool::Search CandidatePool::AnyWithinBudget(const LinkCapsule& cap, ObjectIndex object,
                                                     uint32_t start_node, int budget) {
  if (target_.Ignores(cap.link, object)) return Search::kNone;
  Search result = Search::kNone;
  double radius = cap.radius;
  target_.bvh(object).QueryCapsuleShrinking(
      cap.a, cap.b, &radius,
      [&](uint32_t slot) {
        if (budget == 0) {
          result = Search::kUndecided;
          return false;
        }
        if (budget > 0) --budget;
        if (WithinFromQuery(cap, Candidate{static_cast<uint32_t>(object.value()), slot})) {
          result = Search::kFound;
          return false;
        }
        return true;
      },
      start_node);
  return result;
}

CandidateList CandidatePool::Refine(const CandidateList& parent, const LinkCapsule& cap) {
  ReserveOnFirstUse();
  CandidateList list;
  list.begin = static_cast<uint32_t>(entries_.size());
  if (parent.requery) {
    if (CollectFromBvh(cap)) {
      list.count = static_cast<uint32_t>(entries_.size() - list.begin);
    } else {
      list.requery = true;  // Too many to list: non-empty, keep going.
      list.count = 1;
    }
    return list;
  }
  for (uint32_t k = parent.begin; k < parent.begin + parent.count; ++k) {
    const Candidate c = entries_[k];
    if (Within(cap, c)) entries_.push_back(c);
  }
  list.count = static_cast<uint32_t>(entries_.size() - list.begin);
  return list;
}

bool CandidatePool::Nearest(const PairMotion& motion, LinkIndex link, double s,
                            const CandidateList& list, ContactRecord* best) {
  return target_.NearestOf(motion, link, s, entries_.data() + list.begin, list.count, best,
                           triangle_tests_);
}

}  // namespace sweptccd::internal
