#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): one query,
// as a sequence of named phases over the engine's parts.

#include <optional>
#include <vector>

#include "core/query/candidate_pool.h"
#include "core/query/ccd_query.h"
#include "core/query/cull_batcher.h"
#include "core/query/environment_target.h"
#include "core/query/link_groups.h"
#include "core/query/root_candidates.h"
#include "core/query/swept_bounds.h"
#include "core/query/time_slicer.h"
#include "core/query/witnesses.h"
#include "core/thread_spare.h"

namespace sweptccd::internal {

/// The arrays a query fills (its motion, the whole-pair candidates, the
/// pool, the queue), kept per thread between queries (ThreadSpare) so that
/// a pair allocates almost nothing. Contents are overwritten; only capacity
/// carries.
struct QueryBuffers {
  PairMotion::Storage motion;
  RootCandidates::Buffers roots;
  std::vector<Candidate> pool;
  std::vector<Interval> queue;
  std::vector<double> reach;            // ClearGroups: SubtreeReach.
  std::vector<double> growth;           // Ditto.
  RootCandidates::Buffers loose_roots;  // QueryRun::CullLoose.
  std::vector<char> deferred;           // DeferredLinks: the motion's.
  std::vector<double> stat;             // ClearGroups: StaticGroupBall's.
  std::vector<char> holds_cleared;      // ClearGroups: groups holding a cleared top group.
};

/// Runs one query. Single-use and single-threaded; holds references to the
/// engine's skeleton, environment and filter, and to the options.
class QueryRun {
 public:
  /// `motion`: the pair's motion when the caller has it (built from the
  /// engine's skeleton, pose0, pose1 and options.motion), else built here.
  /// `clears`: intervals proved free ahead of the descent (the device
  /// descent), skipped; nullptr: none.
  QueryRun(const CcdEngine& engine, const Pose& pose0, const Pose& pose1,
           const QueryOptions& options, const PairMotion* motion = nullptr,
           const PairClears* clears = nullptr);
  /// Hands the arrays back to the thread for its next query.
  ~QueryRun();
  QueryRun(const QueryRun&) = delete;
  QueryRun& operator=(const QueryRun&) = delete;

  QueryResult Run();

 private:
  // The members of top-level groups below their roots (LinkGroups::
  // top_roots, those of options.link_group_min_size links and more), whose
  // motion is deferred (PairMotion's `deferred`): in buffers_->deferred;
  // null when there are none.
  const std::vector<char>* DeferredLinks();
  // The phases, in order.
  void ClearGroups();
  void CullLoose();
  LinkIndex CloseLeadingLink();
  // RootCandidates::TouchCheck: TouchesAt(link, 0), kept in touches_at_start_.
  static bool CheckTouchesAtStart(void* self, LinkIndex link);
  void CloseTouchingAtStart(LinkIndex begin, LinkIndex end);
  void CullOpenLinks();
  void SeedRoots();
  void Descend();
  void CloseOutOfWork();

  // Whether the query still looks for contacts (per link: until all links are
  // closed; otherwise until the first).
  bool Searching() const { return options_.per_link || witnesses_.empty(); }
  bool TestsLink(LinkIndex link) const {
    return !target_.IgnoresAll(link) && !witnesses_.done(link);
  }
  // Whether no test finds a triangle of an object some link of the group
  // does not ignore within `ball`.
  bool GroupBallClear(LinkIndex root, LinkCapsule ball);
  // The group rooted at `l`: its ball, centred by BallCentre, tested when
  // narrow enough (SubtreeReach computed on first use: have_reach_).
  // Whether it cleared.
  bool TryGroup(LinkIndex l);
  // Composes the ends of `link` and of its ancestors not composed yet
  // (cleared by their loose capsules), parents first.
  void EnsureEnds(LinkIndex link);
  enum class Step { kNext, kStop };
  // One interval of the descent: cleared, closed, or split into the queue.
  Step Visit(const Interval& interval);
  // A narrow interval: closes it when a sample is within delta (G3).
  bool TryClose(const Interval& interval, const CandidateList& list);
  // The interval's candidates (its capsule given).
  CandidateList CandidatesOf(const Interval& interval, const LinkCapsule& capsule);

  const QueryOptions& options_;
  const Pose& pose0_;  // The pair (the group balls' centres read them).
  const Pose& pose1_;
  const PairClears* const clears_;  // May be null.
  const int num_links_;
  const LinkGroups& groups_;
  // Link groups apply: `articulated`, options.link_groups, the skeleton has
  // groups, and the motion is built here (its ends composed on demand).
  const bool use_groups_;
  // This thread's spare arrays (or new ones when a query on this thread is
  // running already), first so that everything below can start in them
  // and they are handed back last.
  ThreadSpare<QueryBuffers> buffers_;
  std::optional<PairMotion> own_motion_;  // When the caller gave none.
  const PairMotion& motion_;
  EnvironmentTarget target_;
  SweptBounds bounds_;
  TimeSlicer slicer_;
  QueryStats stats_;
  CandidatePool pool_;
  CullBatcher cull_;
  Witnesses witnesses_;
  IntervalQueue queue_;
  std::vector<bool> cleared_by_culler_;  // The culler cleared the link's whole pair.
  // By link, why it is known not open for the pair (its poses are then
  // never composed): 0 (not known), kGroup (a group's ball holding it met
  // nothing: ClearGroups), kLooseCapsule (its loose capsule did: CullLoose).
  static constexpr char kGroup = 1, kLooseCapsule = 2;
  std::vector<char> group_cleared_;
  // SubtreeReach ran (TryGroup): buffers_->reach and growth hold this
  // pair's (CullLoose reads the growth).
  bool have_reach_ = false;
  std::vector<LinkIndex> chain_;  // EnsureEnds's.
  // Whether the link touches at s = 0, once asked during the traversal (-1
  // not asked, 0 no, 1 yes), and where yes, the triangle TouchesAt found
  // (Separation starts from it).
  struct AtStart {
    signed char touches = -1;
    Candidate touching{0, 0};
  };
  std::vector<AtStart> touches_at_start_;
  std::optional<RootCandidates> roots_;  // Which links are open.
  bool out_of_work_ = false;
};

}  // namespace sweptccd::internal
