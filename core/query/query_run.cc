#include "core/query/query_run.h"

#include <algorithm>
#include <vector>

#include "core/errors.h"
#include "core/query/certificate.h"

namespace sweptccd::internal {

namespace {

// Past these sizes a query's arrays are freed instead of kept.
constexpr size_t kKeptLinks = 1024;
constexpr size_t kKeptCandidates = size_t{1} << 16;
constexpr size_t kKeptIntervals = 4096;
// What a group ball may cost (QueryRun::GroupBallClear): triangle tests
// (none: a ball that reaches a triangle the BVH's node and triangle boxes
// cannot refuse is not cleared; its links' loose capsules are tested next,
// and testing the triangles first cost more on the bundled rooms, docs/
// BENCHMARKS-LOG.md 2026-11-28 12:10), and its radius (a wider ball, e.g. a
// whole upper body's, rarely clears a room and walks much of its BVH).
// Past either the group is not cleared.
constexpr int kGroupBudget = 0;
constexpr double kGroupMaxRadiusM = 0.5;

}  // namespace

QueryRun::QueryRun(const CcdEngine& engine, const Pose& pose0, const Pose& pose1,
                   const QueryOptions& options, const PairMotion* motion, const PairClears* clears)
    : options_(options),
      pose0_(pose0),
      pose1_(pose1),
      clears_(clears),
      num_links_(engine.skeleton().num_links()),
      groups_(engine.link_groups()),
      use_groups_(motion == nullptr && options.link_groups &&
                  options.motion == MotionModel::kArticulated && !groups_.empty() &&
                  num_links_ >= options.link_groups_min_links),
      motion_(motion != nullptr
                  ? *motion
                  : own_motion_.emplace(
                        engine.skeleton(), pose0, pose1, options.motion, &buffers_->motion,
                        use_groups_ ? PairMotion::Ends::kOnDemand : PairMotion::Ends::kAll,
                        use_groups_ ? DeferredLinks() : nullptr)),
      target_(engine.skeleton(), engine.environment(), engine.filter()),
      bounds_(engine.skeleton(), motion_, SweptBounds::Tolerance(engine.environment(), motion_)),
      slicer_(pose0.utime, pose1.utime, options.eps_s),
      pool_(target_, options.max_candidates, &stats_.triangle_tests),
      cull_(engine.culler(), bounds_, &stats_),
      witnesses_(target_, motion_, num_links_),
      cleared_by_culler_(num_links_, false),
      group_cleared_(use_groups_ ? num_links_ : 0, 0),
      touches_at_start_(num_links_) {
  pool_.Adopt(std::move(buffers_->pool));
  queue_.Adopt(std::move(buffers_->queue));
  if (use_groups_) witnesses_.SetClearForPair(&group_cleared_);
}

QueryRun::~QueryRun() {
  QueryBuffers& b = *buffers_;
  if (own_motion_.has_value()) own_motion_->Release(&b.motion);
  if (roots_.has_value()) roots_->Release(&b.roots);
  b.pool = pool_.Release();
  b.queue = queue_.Release();
  FreeIfAbove(&b.motion.links, kKeptLinks);
  FreeIfAbove(&b.motion.order, kKeptLinks);
  FreeIfAbove(&b.motion.poses, 3 * kKeptLinks);
  FreeIfAbove(&b.motion.segments, 6 * kKeptLinks);
  FreeIfAbove(&b.roots.links, kKeptLinks);
  FreeIfAbove(&b.roots.link_order, kKeptLinks);
  FreeIfAbove(&b.roots.link_nodes, 2 * kKeptLinks);
  FreeIfAbove(&b.pool, kKeptCandidates);
  FreeIfAbove(&b.queue, kKeptIntervals);
  FreeIfAbove(&b.reach, kKeptLinks);
  FreeIfAbove(&b.growth, kKeptLinks);
  FreeIfAbove(&b.deferred, kKeptLinks);
  FreeIfAbove(&b.stat, kKeptLinks);
  FreeIfAbove(&b.holds_cleared, kKeptLinks);
}

const std::vector<char>* QueryRun::DeferredLinks() {
  std::vector<char>& deferred = buffers_->deferred;
  deferred.assign(num_links_, 0);
  bool any = false;
  for (const LinkIndex root : groups_.top_roots()) {
    if (groups_.end(root) - groups_.begin(root) < options_.link_group_min_size) continue;
    for (const LinkIndex* m = groups_.begin(root) + 1; m != groups_.end(root); ++m) {
      deferred[*m] = 1;
      any = true;
    }
  }
  return any ? &deferred : nullptr;
}

QueryResult QueryRun::Run() {
  // The whole-pair bounds first, on the CPU: a link they clear cannot touch
  // at s = 0 either (its capsule at 0 lies inside them), so the check at the
  // start only looks at the links they leave open. Finding those stops at a
  // link's first primitive. Nothing is listed for the whole pair: its
  // capsules are the fattest of the descent, and the halves' own BVH queries
  // refuse far triangles in groups where refining a long list tests each one.
  if (use_groups_) {
    ClearGroups();
    CullLoose();
  }
  roots_.emplace(target_, bounds_, &pool_, &buffers_->roots,
                 use_groups_ ? &group_cleared_ : nullptr);
  const LinkIndex rest = CloseLeadingLink();
  if (Searching()) {
    // Without --per-link each link found open is checked at s = 0 at once,
    // and the links above the first that touches are not searched: the
    // answer is the lowest touching link. If its witness cannot be measured
    // (rounding), the links above it are searched after all. Per link, every
    // link is searched (no check, no cutoff).
    roots_->FindOpen(rest, options_.per_link ? nullptr : &QueryRun::CheckTouchesAtStart, this);
    const LinkIndex cutoff = roots_->cutoff();
    const LinkIndex end(cutoff.is_valid() ? cutoff + 1 : num_links_);
    CloseTouchingAtStart(rest, end);
    if (Searching() && end < num_links_) {
      roots_->FindOpen(end);
      CloseTouchingAtStart(end, LinkIndex(num_links_));
    }
  }
  if (Searching()) {
    CullOpenLinks();
    SeedRoots();
    Descend();
  }
  if (out_of_work_) CloseOutOfWork();
  QueryResult result;
  result.stats = stats_;
  return witnesses_.Assemble(options_, std::move(result));
}

// Hierarchical link bounds (link_groups.h), parents first: a group whose
// ball meets nothing leaves all its links culled, as their own whole-pair
// capsules (inside the ball) would, so the answer is the same. The balls
// are centred between two input poses (GroupBallAtMidpoint), so no test
// composes a pose or finishes a motion; a cleared group's links never are.
//
// First each top-level group whose members' motion was deferred: its ball
// from the bone lengths (StaticGroupBall), which begins no member but the
// ball's centre; a group it does not clear has its members begun and is
// tried as every other group is.
void QueryRun::ClearGroups() {
  const Skeleton& skeleton = target_.skeleton();
  PairMotion& motion = *own_motion_;
  std::vector<char>& holds_cleared = buffers_->holds_cleared;
  holds_cleared.clear();
  for (const LinkIndex root : groups_.top_roots()) {
    if (groups_.end(root) - groups_.begin(root) < options_.link_group_min_size) continue;
    buffers_->stat.resize(num_links_);
    const LinkCapsule ball = StaticGroupBall(groups_, skeleton, &motion, pose0_, pose1_, root,
                                             bounds_.tolerance_m(), &buffers_->stat);
    if (GroupBallClear(root, ball)) {
      for (const LinkIndex* m = groups_.begin(root); m != groups_.end(root); ++m) {
        group_cleared_[*m] = kGroup;
      }
      ++stats_.groups_cleared;
      // The groups holding it cannot clear now (SubtreeReach gives its
      // members, never begun, an infinite reach): not tried below.
      if (holds_cleared.empty()) holds_cleared.assign(num_links_, 0);
      for (int k = skeleton.link(root).parent; k >= 0; k = skeleton.link(k).parent) {
        holds_cleared[k] = 1;
      }
      continue;
    }
    for (const LinkIndex* m = groups_.begin(root) + 1; m != groups_.end(root); ++m) {
      motion.BeginLink(*m);  // Preorder: parents first.
    }
  }
  for (const LinkIndex l : groups_.preorder()) {
    if (group_cleared_[l] != 0) continue;  // Its top-level group's ball cleared it.
    const int parent = skeleton.link(l).parent;
    if (parent >= 0 && group_cleared_[parent] != 0) {
      group_cleared_[l] = kGroup;
      continue;
    }
    if (groups_.IsRoot(l) && groups_.end(l) - groups_.begin(l) >= options_.link_group_min_size &&
        (holds_cleared.empty() || holds_cleared[l] == 0) && TryGroup(l)) {
      group_cleared_[l] = kGroup;
      ++stats_.groups_cleared;
    }
  }
}

// The links no group cleared: their loose capsules (SweptBounds::LooseOver,
// from the input poses: nothing composed) in one traversal of the scene
// (RootCandidates, without a touch check); a link whose loose capsule meets
// nothing is not open for the pair either (its whole-pair capsule lies
// inside), so it is cleared as a group's links are. Then the ends of the
// links left are composed (with their ancestors'), parents first.
void QueryRun::CullLoose() {
  // SubtreeReach's growth when a group test computed it: the same bits as
  // PairGrowthUpper (no link's motion is finished before this pass).
  const RootCandidates::LoosePoses poses{&pose0_, &pose1_,
                                         have_reach_ ? &buffers_->growth : nullptr};
  RootCandidates loose(target_, bounds_, &pool_, &buffers_->loose_roots, &group_cleared_, &poses);
  loose.FindOpen();
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (group_cleared_[l] == 0 && !loose.Open(l)) {
      group_cleared_[l] = kLooseCapsule;
      ++stats_.loose_cleared;
    }
  }
  RootCandidates::Buffers& kept = buffers_->loose_roots;
  loose.Release(&kept);
  FreeIfAbove(&kept.links, kKeptLinks);
  FreeIfAbove(&kept.link_order, kKeptLinks);
  FreeIfAbove(&kept.link_nodes, 2 * kKeptLinks);
  for (const LinkIndex l : groups_.preorder()) {
    if (group_cleared_[l] == 0) EnsureEnds(l);
  }
}

void QueryRun::EnsureEnds(LinkIndex link) {
  PairMotion& motion = *own_motion_;
  if (motion.EndsReady(link)) return;
  // Ancestors the loose capsules cleared are not composed yet: first them.
  chain_.clear();
  for (LinkIndex l = link; l.is_valid() && !motion.EndsReady(l); l = motion.motion_parent(l)) {
    chain_.push_back(l);
  }
  for (auto it = chain_.rbegin(); it != chain_.rend(); ++it) motion.CompleteEnds(*it);
}

bool QueryRun::TryGroup(LinkIndex l) {
  const PairMotion& motion = *own_motion_;
  const Skeleton& skeleton = target_.skeleton();
  if (!have_reach_) {
    SubtreeReach(groups_, skeleton, motion, &buffers_->reach, &buffers_->growth);
    have_reach_ = true;
  }
  // A group reaching past twice the largest ball tested is not centred
  // (its ball would hardly be narrow enough): skipped.
  if (!(buffers_->reach[l] <= 2 * kGroupMaxRadiusM)) return false;
  double radius = 0;
  const LinkIndex centre =
      BallCentre(groups_, skeleton, motion, buffers_->reach, buffers_->growth, l, &radius);
  if (!(radius <= kGroupMaxRadiusM)) return false;  // GroupBallClear would refuse it.
  return GroupBallClear(
      l, GroupBallAtMidpoint(motion, pose0_, pose1_, centre, radius, bounds_.tolerance_m()));
}

bool QueryRun::GroupBallClear(LinkIndex root, LinkCapsule ball) {
  if (!(ball.radius <= kGroupMaxRadiusM)) return false;
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    // The ball asks as a member that does not ignore the object (the pool
    // skips objects its capsule's link ignores); none: nothing to ask.
    ball.link = LinkIndex();
    for (const LinkIndex* m = groups_.begin(root); m != groups_.end(root); ++m) {
      if (!target_.Ignores(*m, o)) {
        ball.link = *m;
        break;
      }
    }
    // A bounded search: past kGroupBudget triangle tests the group is not
    // cleared (its links are then tested on their own: their loose
    // capsules, then their whole-pair capsules).
    if (ball.link.is_valid() &&
        pool_.AnyWithinBudget(ball, o, 0, kGroupBudget) != CandidatePool::Search::kNone) {
      return false;
    }
  }
  return true;
}

// A link touching at s = 0 answers at once: [0, w] with w the first dyadic
// width that meets G2 (the interval the chronological descent would reach),
// the witness at s = 0 (separation <= 0 <= delta); G1 is empty.
//
// Only links the whole-pair bounds leave open can touch at 0: the swept
// capsule over [0, 1] contains the link at 0 (its tolerance covers the
// rounding of both distances), and a link it clears meets no triangle in it.
void QueryRun::CloseTouchingAtStart(LinkIndex begin, LinkIndex end) {
  const double w = slicer_.FirstNarrowWidth();
  for (LinkIndex l = begin; l < end; ++l) {
    if (!roots_->Open(l) || target_.IgnoresAll(l)) continue;
    AtStart& at_start = touches_at_start_[l];
    if (at_start.touches < 0) {
      at_start.touches = target_.TouchesAt(motion_, l, 0.0, 0.0, &at_start.touching) ? 1 : 0;
    }
    if (at_start.touches == 0) continue;
    ContactRecord at_zero;
    if (!target_.Separation(motion_, l, 0.0, 0.0, &at_zero, &at_start.touching)) {
      continue;  // Rounding: retry later.
    }
    ++stats_.links_tested;
    witnesses_.CloseLeaf(l, 0, w, at_zero, /*exact_witness=*/true);
    if (!options_.per_link) break;
  }
}

// FindOpen's touch check: TouchesAt at s = 0, kept for CloseTouchingAtStart.
bool QueryRun::CheckTouchesAtStart(void* self, LinkIndex link) {
  QueryRun& run = *static_cast<QueryRun*>(self);
  AtStart& at_start = run.touches_at_start_[link];
  const bool touches = run.target_.TouchesAt(run.motion_, link, 0.0, 0.0, &at_start.touching);
  at_start.touches = touches ? 1 : 0;
  return touches;
}

// The published method's culling step, on the culler (the GPU): the swept
// bound over the whole pair (and the first levels below it) of every link
// the CPU's whole-pair bounds left open, in one round trip. A link it clears
// is free for the pair without CPU descent. Asked only after the CPU has
// found the open links and answered the start: a pair touching at s = 0, or
// with every link clear of the scene, costs no round trip (one round trip
// costs more than the CPU's whole pair on every device measured, docs/GPU.md).
void QueryRun::CullOpenLinks() {
  if (!cull_.active()) return;
  bool any = false;
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (!TestsLink(l) || !roots_->Open(l)) continue;
    cull_.AppendSubtree(l, 0, 1, bounds_.EndsOver(l, 0, 1), CullBatcher::kLevels);
    any = true;
  }
  if (!any || !cull_.Flush()) return;
  for (LinkIndex l(0); l < num_links_; ++l) {
    const CullAnswer* root = cull_.Find(l, 0, 1);
    cleared_by_culler_[l] = root != nullptr && root->cleared;
  }
}

// Without --per-link the answer at s = 0 is the lowest link (by index) that
// touches there, so link 0 is decided first, alone: when it touches, no other
// link's whole-pair capsule is searched. Link 0 is the skeleton's root in the
// usual files and imports (the pelvis), the link a seated user rests on a
// chair with, pair after pair; the search of the other links' capsules near a
// chair's dense mesh cost a seated avatar's pairs four times the rest (docs/
// BENCHMARKS.md, "Short candidate lists"). Returns the first link left to the
// traversal over all links.
LinkIndex QueryRun::CloseLeadingLink() {
  if (options_.per_link || num_links_ == 0) return LinkIndex(0);
  const LinkIndex first(0);
  if (!target_.IgnoresAll(first) && roots_->FindOpenOne(first)) {
    CloseTouchingAtStart(first, LinkIndex(1));
  }
  return LinkIndex(1);
}

// Seeding: the links the whole-pair bounds leave open start the descent, with
// no list (their halves query the BVHs).
void QueryRun::SeedRoots() {
  const RootCandidates& roots = *roots_;
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (!TestsLink(l)) continue;
    if (cleared_by_culler_[l] || !roots.Open(l)) {
      ++stats_.links_culled;
      continue;
    }
    // The device descent cleared the whole pair for the link (as a culler
    // would: the same skip as cleared_by_culler_).
    if (clears_ != nullptr && clears_->Cleared(l, 0, 0.0, 1.0)) {
      ++stats_.links_culled;
      ++stats_.cull_cleared;
      continue;
    }
    ++stats_.links_tested;
    Interval root;
    root.link = l;
    root.candidates = roots.ListOf(l);
    root.prefiltered = true;
    root.ends = bounds_.EndsOver(l, 0, 1);
    queue_.push(root);
  }
}

// The chronological descent over every open link's intervals, until the
// first contact (or, per link, every link's), or out of work.
void QueryRun::Descend() {
  while (!queue_.empty() && Searching()) {
    const Interval interval = queue_.top();
    queue_.pop();
    if (witnesses_.done(interval.link)) continue;
    // Work limit, and a memory limit on the candidate pool (64 M entries,
    // 512 MiB) so a raised work limit cannot exhaust memory.
    if (++stats_.intervals > options_.max_intervals || pool_.size() > (64u << 20)) {
      out_of_work_ = true;
      queue_.push(interval);
      return;
    }
    if (Visit(interval) == Step::kStop) return;
  }
}

QueryRun::Step QueryRun::Visit(const Interval& interval) {
  const CullAnswer* answer = nullptr;
  // Proved free by the device descent: an interval this test would clear.
  if (!interval.prefiltered && clears_ != nullptr &&
      clears_->Cleared(interval.link, interval.depth, interval.s0, interval.s1)) {
    ++stats_.cull_cleared;
    return Step::kNext;
  }
  if (!interval.prefiltered) {
    answer = cull_.AnswerFor(interval, queue_.pending(), witnesses_.done());
    if (answer != nullptr && answer->cleared) {
      ++stats_.cull_cleared;
      return Step::kNext;  // Certified free over [s0, s1] by the culler.
    }
  }
  // The swept capsule: already computed when the culler was asked.
  const LinkCapsule capsule =
      answer != nullptr ? answer->capsule
                        : bounds_.FromEnds(interval.link, interval.s0, interval.s1, interval.ends);
  const CandidateList list = CandidatesOf(interval, capsule);
  if (list.count == 0) return Step::kNext;  // Certified free over [s0, s1].
  if (slicer_.Narrow(interval.s0, interval.s1) && TryClose(interval, list)) {
    return options_.per_link ? Step::kNext : Step::kStop;
  }
  Interval lower, upper;
  if (!TimeSlicer::Split(interval, capsule, list, &lower, &upper)) {
    witnesses_.CloseUndecided(interval.link, interval.s0);  // Cannot split further.
    return options_.per_link ? Step::kNext : Step::kStop;
  }
  queue_.push(lower);
  queue_.push(upper);
  return Step::kNext;
}

CandidateList QueryRun::CandidatesOf(const Interval& interval, const LinkCapsule& capsule) {
  if (!interval.prefiltered) return pool_.Refine(interval.candidates, capsule);
  // The root interval: seeding already tested this capsule.
  CandidateList list = interval.candidates;
  if (list.requery) list.count = 1;
  return list;
}

bool QueryRun::TryClose(const Interval& interval, const CandidateList& list) {
  ContactRecord best, sample;
  bool have = false;
  const double mid = 0.5 * (interval.s0 + interval.s1);
  for (double s : {interval.s0, mid, interval.s1}) {
    // With no list (a dense region), ask the target for the nearest
    // primitive within delta of the capsule instead.
    const bool got = list.requery
                         ? target_.Separation(motion_, interval.link, s, options_.delta_m, &sample)
                         : pool_.Nearest(motion_, interval.link, s, list, &sample);
    if (got && (!have || sample.separation < best.separation)) {
      best = sample;
      have = true;
    }
  }
  // G3 with the slack as margin (certificate.h).
  if (!have || best.separation > AcceptedSeparation(options_.delta_m, bounds_.tolerance_m())) {
    return false;
  }
  witnesses_.CloseLeaf(interval.link, interval.s0, interval.s1, best);
  return true;
}

// Out of work: every link with work left is undecided from its earliest
// open interval (certificate.h).
void QueryRun::CloseOutOfWork() {
  OpenWork open(num_links_);
  while (!queue_.empty()) {
    const Interval& t = queue_.top();
    if (!witnesses_.done(t.link)) open.Note(t.link, t.s0);
    queue_.pop();
    if (!options_.per_link) break;  // The top one is the earliest of all.
  }
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (open.open(l)) witnesses_.CloseUndecided(l, open.earliest(l));
  }
}

}  // namespace sweptccd::internal
