#include "core/query/ccd_query.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_map>

#include "core/geometry/distance.h"
#include "core/errors.h"

namespace sweptccd {

std::string ValidateQueryOptions(const QueryOptions& options) {
  if (!std::isfinite(options.eps_s) || !(options.eps_s > 0)) {
    return "eps must be a finite number of seconds > 0, got " + std::to_string(options.eps_s);
  }
  if (!std::isfinite(options.delta_m) || !(options.delta_m > 0)) {
    return "delta must be a finite number of metres > 0, got " + std::to_string(options.delta_m);
  }
  if (options.max_intervals < 1) return "the work limit must be at least 1 interval";
  if (options.max_candidates < 1) return "max_candidates must be at least 1";
  return {};
}

double PairDurationUs(int64_t utime0, int64_t utime1) {
  // long double holds any int64 exactly, so the difference is exact there.
  return static_cast<double>(static_cast<long double>(utime1) - static_cast<long double>(utime0));
}

namespace {

long double ExactTime(int64_t utime0, int64_t utime1, double s) {
  return static_cast<long double>(utime0) +
         static_cast<long double>(s) *
             (static_cast<long double>(utime1) - static_cast<long double>(utime0));
}

}  // namespace

double BracketTimeLo(int64_t utime0, int64_t utime1, double s) {
  const long double exact = ExactTime(utime0, utime1, s);
  double t = static_cast<double>(exact);
  if (static_cast<long double>(t) > exact) t = std::nextafter(t, -HUGE_VAL);
  return t;
}

double BracketTimeHi(int64_t utime0, int64_t utime1, double s) {
  const long double exact = ExactTime(utime0, utime1, s);
  double t = static_cast<double>(exact);
  if (static_cast<long double>(t) < exact) t = std::nextafter(t, HUGE_VAL);
  return t;
}

namespace {

// A candidate triangle: object index and BVH slot.
struct Candidate {
  uint32_t object;
  uint32_t slot;
};

// A time interval of one link still to be cleared.
struct Task {
  double s0, s1;
  int link;
  int depth;
  uint32_t cand_begin;  // Parent's kept candidates in the pool...
  uint32_t cand_count;
  bool requery;      // ...or, when true, query the BVHs afresh.
  bool prefiltered;  // The list was built for exactly this interval.
  // The link's segment at s0 and at s1, shared with the parent interval.
  Eigen::Vector3d a0, b0, a1, b1;
};

struct TaskLater {
  bool operator()(const Task& x, const Task& y) const {
    if (x.s0 != y.s0) return x.s0 > y.s0;
    return x.link > y.link;
  }
};

// The chronological queue, with its pending tasks readable (for batching
// culler round trips over them).
class TaskQueue : public std::priority_queue<Task, std::vector<Task>, TaskLater> {
 public:
  const std::vector<Task>& pending() const { return c; }
};

// A time interval of one link, as the culler's answers are keyed.
struct IntervalKey {
  int link;
  double s0, s1;
  bool operator==(const IntervalKey& o) const {
    return link == o.link && s0 == o.s0 && s1 == o.s1;
  }
};

struct IntervalKeyHash {
  size_t operator()(const IntervalKey& k) const {
    return std::hash<double>()(k.s0) * 1000003u ^ std::hash<double>()(k.s1) * 31u ^
           static_cast<size_t>(k.link);
  }
};

// Levels of the time-slicing tree below an interval that one culler round
// trip answers ahead of the descent (15 intervals per interval asked about),
// and the most capsules sent in one round trip.
constexpr int kCullLevels = 3;
constexpr size_t kMaxCullBatch = 4096;

// Swept bound of one link over [s0, s1]: a capsule around the segment at the
// midpoint. Every point of the link over the interval lies inside it.
struct Capsule {
  Eigen::Vector3d a, b;
  double radius;
};

Eigen::Vector3d UnitNormal(const SegmentTriangleResult& r, const Eigen::Vector3d& seg_a,
                           const Eigen::Vector3d& seg_b, const Eigen::Vector3d& ta,
                           const Eigen::Vector3d& tb, const Eigen::Vector3d& tc) {
  const Eigen::Vector3d d = r.p_segment - r.p_triangle;
  const double len = d.norm();
  if (len > 1e-12) return d / len;
  // The segment meets the triangle: use the face normal, on the side of the
  // segment's farther end (the link is mostly there).
  Eigen::Vector3d n = (tb - ta).cross(tc - ta);
  if (n.norm() > 0) {
    n.normalize();
    const double da = n.dot(seg_a - r.p_triangle), db = n.dot(seg_b - r.p_triangle);
    return (std::fabs(da) >= std::fabs(db) ? da : db) < 0 ? -n : n;
  }
  // Degenerate triangle crossed by the segment: any direction across the segment.
  Eigen::Vector3d axis = seg_b - seg_a;
  if (axis.norm() == 0) return Eigen::Vector3d(0, 0, 1);
  Eigen::Vector3d perp = axis.cross(Eigen::Vector3d::UnitX());
  if (perp.norm() < 1e-6 * axis.norm()) perp = axis.cross(Eigen::Vector3d::UnitY());
  return perp.normalized();
}

class QueryRun {
 public:
  QueryRun(const CcdEngine& engine, const Pose& pose0, const Pose& pose1,
           const QueryOptions& options)
      : engine_(engine),
        skel_(engine.skeleton()),
        env_(engine.environment()),
        filter_(engine.filter()),
        options_(options),
        motion_(skel_, pose0, pose1, options.motion),
        utime0_(pose0.utime),
        utime1_(pose1.utime),
        dt_us_(PairDurationUs(pose0.utime, pose1.utime)),
        eps_us_(options.eps_s * 1e6),
        // The environment's float storage, and the rounding of the distance
        // routines: at most ~2e-8 of the coordinates' magnitude (see
        // tests/core/distance_test.cc); 2^-22 of the avatar's is ten times that.
        tol_(std::max(env_.coordinate_tolerance(),
                      std::ldexp(motion_.coordinate_scale(), -22) + 1e-9)),
        culler_(engine.culler()) {}

  QueryResult Run();

 private:
  Capsule SweptCapsule(int link, double s0, double s1) const {
    Capsule c;
    double growth;
    motion_.SweptCapsule(link, s0, s1, &c.a, &c.b, &growth);
    c.radius = skel_.link(link).radius + growth + tol_;
    return c;
  }
  bool WithinCapsule(const Capsule& cap, const Candidate& c) {
    Eigen::Vector3d ta, tb, tc;
    env_.object(c.object).bvh.Triangle(c.slot, &ta, &tb, &tc);
    ++result_.stats.triangle_tests;
    // Cheap answers first: the triangle's bounding sphere around ta misses
    // the capsule (reject), or a vertex is inside it (accept). Both compare
    // squared distances with a relative margin of 1e-9 towards "inside".
    const Eigen::Vector3d d = cap.b - cap.a;
    const double dd = d.squaredNorm();
    const double reach = std::sqrt(std::max((tb - ta).squaredNorm(), (tc - ta).squaredNorm()));
    const double da = PointSegmentDistanceSquared(ta, cap.a, d, dd);
    const double far = cap.radius + reach;
    if (da > far * far * (1 + 1e-9)) return false;
    if (da <= cap.radius * cap.radius * (1 - 1e-9) ||
        PointSegmentDistanceSquared(tb, cap.a, d, dd) <= cap.radius * cap.radius * (1 - 1e-9) ||
        PointSegmentDistanceSquared(tc, cap.a, d, dd) <= cap.radius * cap.radius * (1 - 1e-9)) {
      return true;
    }
    return SegmentTriangleDistance(cap.a, cap.b, ta, tb, tc).distance <= cap.radius;
  }
  // Appends to the pool every unfiltered triangle within the capsule, found
  // through the BVHs (from `start_node` of one object when object >= 0).
  // Returns false (and appends nothing) past max_candidates.
  bool CollectFromBvh(int link, const Capsule& cap, int object, uint32_t start_node);
  void InitialCandidates();
  void CollectDual(const std::vector<int>& links, int object, uint32_t env_node);
  // Exact separation of `link` at s over the candidates in the pool range.
  bool BestSample(int link, double s, uint32_t begin, uint32_t count, ContactRecord* best);
  void FinishLeaf(const Task& task, const ContactRecord& witness, bool exact_witness = false);
  void FinishUndecided(int link, double s_lo);
  bool InitiallyTouching(int link);
  // Culler: appends the swept capsule of [s0, s1] and of its descendants
  // `levels` deep, computed exactly as the descent computes them.
  void AppendSubtree(int link, double s0, double s1, const Eigen::Vector3d& a0,
                     const Eigen::Vector3d& b0, const Eigen::Vector3d& a1,
                     const Eigen::Vector3d& b1, int levels);
  // Sends the pending capsules in one round trip and records the answers.
  // Returns false (and drops the culler for this query) when it failed.
  bool FlushCull();
  // The culler's answer for the interval, with its capsule (the one the
  // descent would compute); nullptr when it was not asked.
  struct CullAnswer {
    bool cleared;
    Capsule cap;
  };
  const CullAnswer* Culled(int link, double s0, double s1) const;
  // One round trip for `task` and, while the batch has room, the other
  // pending tasks the culler has not answered.
  void CullAhead(const Task& task);

  const CcdEngine& engine_;
  const Skeleton& skel_;
  const Environment& env_;
  const CollisionFilter& filter_;
  const QueryOptions& options_;
  PairMotion motion_;
  int64_t utime0_, utime1_;
  double dt_us_, eps_us_, tol_;

  std::vector<Candidate> pool_;
  std::vector<Capsule> top_capsule_;
  std::vector<Aabb> top_box_;
  std::vector<uint32_t> top_begin_, top_count_;
  std::vector<bool> top_overflow_;
  std::vector<bool> link_done_;
  TaskQueue queue_;
  QueryResult result_;

  const CapsuleCuller* culler_;
  std::vector<CullCapsule> cull_batch_;
  std::vector<IntervalKey> cull_keys_;
  std::vector<uint8_t> cull_answer_;
  std::unordered_map<IntervalKey, CullAnswer, IntervalKeyHash> cull_answers_;
  std::vector<bool> culled_link_;  // The culler cleared the link's whole pair.
};

void QueryRun::AppendSubtree(int link, double s0, double s1, const Eigen::Vector3d& a0,
                             const Eigen::Vector3d& b0, const Eigen::Vector3d& a1,
                             const Eigen::Vector3d& b1, int levels) {
  CullCapsule c;
  double growth;
  motion_.SweptCapsuleFromEnds(link, s0, s1, a0, b0, a1, b1, &c.a, &c.b, &growth);
  c.radius = skel_.link(link).radius + growth + tol_;
  c.link = link;
  cull_batch_.push_back(c);
  cull_keys_.push_back(IntervalKey{link, s0, s1});
  const double mid = 0.5 * (s0 + s1);
  if (levels == 0 || !(mid > s0 && mid < s1)) return;
  const Eigen::Vector3d am = c.a, bm = c.b;  // The segment at mid.
  AppendSubtree(link, s0, mid, a0, b0, am, bm, levels - 1);
  AppendSubtree(link, mid, s1, am, bm, a1, b1, levels - 1);
}

bool QueryRun::FlushCull() {
  if (cull_batch_.empty() || culler_ == nullptr) return culler_ != nullptr;
  const bool ok = culler_->Cull(cull_batch_, &cull_answer_);
  if (ok) {
    ++result_.stats.cull_round_trips;
    result_.stats.cull_capsules += static_cast<int64_t>(cull_batch_.size());
    for (size_t i = 0; i < cull_keys_.size(); ++i) {
      const CullCapsule& c = cull_batch_[i];
      cull_answers_[cull_keys_[i]] = CullAnswer{cull_answer_[i] == 0, Capsule{c.a, c.b, c.radius}};
    }
  } else {
    culler_ = nullptr;  // Failed (logged by the culler): the CPU decides alone.
  }
  cull_batch_.clear();
  cull_keys_.clear();
  return ok;
}

const QueryRun::CullAnswer* QueryRun::Culled(int link, double s0, double s1) const {
  const auto it = cull_answers_.find(IntervalKey{link, s0, s1});
  return it == cull_answers_.end() ? nullptr : &it->second;
}

void QueryRun::CullAhead(const Task& task) {
  AppendSubtree(task.link, task.s0, task.s1, task.a0, task.b0, task.a1, task.b1, kCullLevels);
  const size_t per_task = cull_batch_.size();
  for (const Task& t : queue_.pending()) {
    if (cull_batch_.size() + per_task > kMaxCullBatch) break;
    if (link_done_[t.link] || t.prefiltered || Culled(t.link, t.s0, t.s1) != nullptr) continue;
    AppendSubtree(t.link, t.s0, t.s1, t.a0, t.b0, t.a1, t.b1, kCullLevels);
  }
  FlushCull();
}

bool QueryRun::CollectFromBvh(int link, const Capsule& cap, int object, uint32_t start_node) {
  const size_t start = pool_.size();
  bool overflow = false;
  for (int o = 0; o < env_.num_objects(); ++o) {
    if ((object >= 0 && o != object) || filter_.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env_.object(o).bvh;
    double radius = cap.radius;
    bvh.QueryCapsuleShrinking(
        cap.a, cap.b, &radius,
        [&](uint32_t slot) {
          const Candidate c{static_cast<uint32_t>(o), slot};
          if (!WithinCapsule(cap, c)) return true;
          pool_.push_back(c);
          // Past the cap the list is not worth keeping: stop early.
          overflow = pool_.size() - start > static_cast<size_t>(options_.max_candidates);
          return !overflow;
        },
        object >= 0 ? start_node : 0);
    if (overflow) break;
  }
  if (overflow) pool_.resize(start);
  return !overflow;
}

// The published method's culling step: a BVH over the links' swept bounds for
// the whole pair, traversed together with each object's BVH. Links whose bound
// meets no triangle are free for the whole pair.
void QueryRun::CollectDual(const std::vector<int>& links, int object, uint32_t env_node) {
  const TriangleBvh& bvh = env_.object(object).bvh;
  const Aabb env_box = bvh.NodeBox(env_node);
  Aabb box{Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()),
           Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity())};
  std::vector<int> live;
  for (int l : links) {
    if (top_box_[l].Overlaps(env_box)) {
      live.push_back(l);
      box.lo = box.lo.cwiseMin(top_box_[l].lo);
      box.hi = box.hi.cwiseMax(top_box_[l].hi);
    }
  }
  if (live.empty()) return;
  if (live.size() == 1) {
    const int l = live[0];
    if (top_overflow_[l]) return;
    // Gather this link's candidates below env_node into its own run of the
    // pool. Runs of one link from different nodes are contiguous because the
    // traversal finishes a link leaf before moving on (see below).
    const size_t before = pool_.size();
    if (!CollectFromBvh(l, top_capsule_[l], object, env_node)) {
      top_overflow_[l] = true;
      return;
    }
    const uint32_t added = static_cast<uint32_t>(pool_.size() - before);
    if (added == 0) return;
    // Move the new run next to the link's earlier run, if any.
    if (top_count_[l] == 0) {
      top_begin_[l] = static_cast<uint32_t>(before);
    } else if (top_begin_[l] + top_count_[l] != before) {
      std::vector<Candidate> merged(pool_.begin() + top_begin_[l],
                                    pool_.begin() + top_begin_[l] + top_count_[l]);
      merged.insert(merged.end(), pool_.begin() + before, pool_.end());
      pool_.resize(before);
      top_begin_[l] = static_cast<uint32_t>(pool_.size());
      pool_.insert(pool_.end(), merged.begin(), merged.end());
      top_count_[l] = static_cast<uint32_t>(merged.size());
      if (top_count_[l] > static_cast<uint32_t>(options_.max_candidates)) top_overflow_[l] = true;
      return;
    }
    top_count_[l] += added;
    if (top_count_[l] > static_cast<uint32_t>(options_.max_candidates)) top_overflow_[l] = true;
    return;
  }
  const TriangleBvh::Node& node = bvh.nodes()[env_node];
  const Eigen::Vector3d link_ext = box.hi - box.lo;
  const Eigen::Vector3d env_ext = env_box.hi - env_box.lo;
  const bool split_links =
      node.count > 0 || link_ext.maxCoeff() >= env_ext.maxCoeff();
  if (!split_links) {
    CollectDual(live, object, node.first);
    CollectDual(live, object, node.first + 1);
    return;
  }
  // Split the links at the median of their box centres along the widest axis.
  int axis = 0;
  link_ext.maxCoeff(&axis);
  std::sort(live.begin(), live.end(), [&](int x, int y) {
    const double cx = top_box_[x].lo[axis] + top_box_[x].hi[axis];
    const double cy = top_box_[y].lo[axis] + top_box_[y].hi[axis];
    return cx != cy ? cx < cy : x < y;
  });
  const size_t half = live.size() / 2;
  CollectDual(std::vector<int>(live.begin(), live.begin() + half), object, env_node);
  CollectDual(std::vector<int>(live.begin() + half, live.end()), object, env_node);
}

void QueryRun::InitialCandidates() {
  const int n = skel_.num_links();
  top_capsule_.resize(n);
  top_box_.resize(n);
  top_begin_.assign(n, 0);
  top_count_.assign(n, 0);
  top_overflow_.assign(n, false);
  for (int l = 0; l < n; ++l) {
    top_capsule_[l] = SweptCapsule(l, 0, 1);
    const Capsule& c = top_capsule_[l];
    top_box_[l].lo = c.a.cwiseMin(c.b).array() - c.radius;
    top_box_[l].hi = c.a.cwiseMax(c.b).array() + c.radius;
  }
  for (int o = 0; o < env_.num_objects(); ++o) {
    std::vector<int> links;
    for (int l = 0; l < n; ++l) {
      if (!filter_.Ignores(l, o) && !culled_link_[l]) links.push_back(l);
    }
    if (!links.empty()) CollectDual(links, o, 0);
  }
  // An overflowing link's partial runs are useless; it queries the BVHs per
  // interval instead.
  for (int l = 0; l < n; ++l) {
    if (top_overflow_[l]) top_count_[l] = 0;
  }
}

bool QueryRun::BestSample(int link, double s, uint32_t begin, uint32_t count,
                          ContactRecord* best) {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion_.SegmentAt(link, s, &a, &b);
  const double radius = skel_.link(link).radius;
  bool found = false;
  for (uint32_t k = begin; k < begin + count; ++k) {
    const Candidate& c = pool_[k];
    env_.object(c.object).bvh.Triangle(c.slot, &ta, &tb, &tc);
    ++result_.stats.triangle_tests;
    const SegmentTriangleResult r = SegmentTriangleDistance(a, b, ta, tb, tc);
    const double sep = r.distance - radius;
    if (!found || sep < best->separation) {
      found = true;
      best->link = link;
      best->object = static_cast<int>(c.object);
      best->triangle = env_.object(c.object).bvh.TriangleId(c.slot);
      best->s = s;
      best->point_link = r.p_segment;
      best->point_env = r.p_triangle;
      best->normal = UnitNormal(r, a, b, ta, tb, tc);
      best->separation = sep;
    }
  }
  return found;
}

bool QueryRun::InitiallyTouching(int link) { return engine_.TouchesAt(motion_, link, 0.0, 0.0); }

void QueryRun::FinishLeaf(const Task& task, const ContactRecord& witness, bool exact_witness) {
  LinkBracket bracket;
  bracket.link = task.link;
  bracket.s_lo = task.s0;
  bracket.s_hi = task.s1;
  bracket.has_witness = true;
  bracket.witness = witness;
  // The candidates hold every triangle that can touch; one outside them can
  // still be the nearest when nothing touches. Make the witness exact.
  ContactRecord exact;
  if (!exact_witness &&
      engine_.Separation(motion_, task.link, witness.s, witness.separation, &exact) &&
      exact.separation < witness.separation) {
    bracket.witness = exact;
  }
  bracket.initially_colliding =
      task.s0 == 0 && ((bracket.witness.s == 0 && bracket.witness.separation <= 0) ||
                       InitiallyTouching(task.link));
  result_.links.push_back(bracket);
  link_done_[task.link] = true;
}

void QueryRun::FinishUndecided(int link, double s_lo) {
  LinkBracket bracket;
  bracket.link = link;
  bracket.s_lo = s_lo;
  bracket.s_hi = 1;
  bracket.undecided = true;
  ContactRecord r;
  // Best effort: the nearest triangle at s_lo (any distance).
  if (engine_.Separation(motion_, link, s_lo, 1e12, &r)) {
    bracket.has_witness = true;
    bracket.witness = r;
  }
  bracket.initially_colliding = s_lo == 0 && InitiallyTouching(link);
  result_.links.push_back(bracket);
  link_done_[link] = true;
}

QueryResult QueryRun::Run() {
  const int n = skel_.num_links();
  link_done_.assign(n, false);
  pool_.reserve(1024);
  // A link touching at s = 0 answers at once: [0, w] with w the first
  // dyadic width that meets G2 (the interval the chronological descent would
  // reach), the witness at s = 0 (separation <= 0 <= delta); G1 is empty.
  {
    double w = 1;
    while (w > 1e-300 && ((w * dt_us_ > eps_us_) ||
                          BracketTimeHi(utime0_, utime1_, w) - BracketTimeLo(utime0_, utime1_, 0) >
                              eps_us_)) {
      w *= 0.5;
    }
    for (int l = 0; l < n; ++l) {
      if (filter_.IgnoresAll(l) || !engine_.TouchesAt(motion_, l, 0.0, 0.0)) continue;
      ContactRecord at_zero;
      if (!engine_.Separation(motion_, l, 0.0, 0.0, &at_zero)) continue;  // Rounding: retry later.
      Task leaf{0, w, l, 0, 0, 0, false, false, {}, {}, {}, {}};
      ++result_.stats.links_tested;
      FinishLeaf(leaf, at_zero, /*exact_witness=*/true);
      if (!options_.per_link) break;
    }
  }
  culled_link_.assign(n, false);
  if (culler_ != nullptr && (options_.per_link || result_.links.empty())) {
    // The published method's culling step, on the culler: every link's swept
    // bound over the whole pair (and the first levels below it) in one round
    // trip. A link it clears is free for the pair without CPU work.
    for (int l = 0; l < n; ++l) {
      if (filter_.IgnoresAll(l) || link_done_[l]) continue;
      Eigen::Vector3d a0, b0, a1, b1;
      motion_.SegmentAt(l, 0, &a0, &b0);
      motion_.SegmentAt(l, 1, &a1, &b1);
      AppendSubtree(l, 0, 1, a0, b0, a1, b1, kCullLevels);
    }
    if (FlushCull()) {
      for (int l = 0; l < n; ++l) {
        const CullAnswer* root = Culled(l, 0, 1);
        culled_link_[l] = root != nullptr && root->cleared;
      }
    }
  }
  if (options_.per_link || result_.links.empty()) InitialCandidates();
  for (int l = 0; l < n && (options_.per_link || result_.links.empty()); ++l) {
    if (filter_.IgnoresAll(l) || link_done_[l]) continue;
    if (culled_link_[l] || (top_count_[l] == 0 && !top_overflow_[l])) {
      ++result_.stats.links_culled;
      continue;
    }
    ++result_.stats.links_tested;
    Task root{0, 1, l, 0, top_begin_[l], top_count_[l], static_cast<bool>(top_overflow_[l]), true,
              {}, {}, {}, {}};
    motion_.SegmentAt(l, 0, &root.a0, &root.b0);
    motion_.SegmentAt(l, 1, &root.a1, &root.b1);
    queue_.push(root);
  }
  bool out_of_work = false;
  while (!queue_.empty() && (options_.per_link || result_.links.empty())) {
    const Task task = queue_.top();
    queue_.pop();
    if (link_done_[task.link]) continue;
    // Work limit, and a memory limit on the candidate pool (64 M entries,
    // 512 MiB) so a raised work limit cannot exhaust memory.
    if (++result_.stats.intervals > options_.max_intervals || pool_.size() > (64u << 20)) {
      out_of_work = true;
      queue_.push(task);
      break;
    }
    // Triangles that can touch the link during the task's interval.
    uint32_t begin = static_cast<uint32_t>(pool_.size());
    uint32_t count = 0;
    bool requery = false;
    const CullAnswer* answer = nullptr;
    if (culler_ != nullptr && !task.prefiltered) {
      answer = Culled(task.link, task.s0, task.s1);
      if (answer == nullptr) {
        CullAhead(task);
        answer = Culled(task.link, task.s0, task.s1);  // nullptr if the culler failed.
      }
      if (answer != nullptr && answer->cleared) {
        ++result_.stats.cull_cleared;
        continue;  // Certified free over [s0, s1] by the culler.
      }
    }
    // The swept capsule: already computed when the culler was asked.
    Capsule cap;
    if (answer != nullptr) {
      cap = answer->cap;
    } else {
      double growth;
      motion_.SweptCapsuleFromEnds(task.link, task.s0, task.s1, task.a0, task.b0, task.a1,
                                   task.b1, &cap.a, &cap.b, &growth);
      cap.radius = skel_.link(task.link).radius + growth + tol_;
    }
    if (task.prefiltered) {
      // The root interval: InitialCandidates already tested this capsule.
      begin = task.cand_begin;
      count = task.requery ? 1 : task.cand_count;
      requery = task.requery;
    } else {
      if (task.requery) {
        if (CollectFromBvh(task.link, cap, -1, 0)) {
          count = static_cast<uint32_t>(pool_.size() - begin);
        } else {
          requery = true;  // Too many to list: non-empty, keep going.
          count = 1;
        }
      } else {
        for (uint32_t k = task.cand_begin; k < task.cand_begin + task.cand_count; ++k) {
          const Candidate c = pool_[k];
          if (WithinCapsule(cap, c)) pool_.push_back(c);
        }
        count = static_cast<uint32_t>(pool_.size() - begin);
      }
    }
    if (count == 0) continue;  // Certified free over [s0, s1].

    const double t_lo = BracketTimeLo(utime0_, utime1_, task.s0);
    const double t_hi = BracketTimeHi(utime0_, utime1_, task.s1);
    // G2 in both readings: the width in s times the pair's duration, and the
    // difference of the printed times (which rounds at epoch-size utimes).
    if ((task.s1 - task.s0) * dt_us_ <= eps_us_ && t_hi - t_lo <= eps_us_) {
      // Narrow enough: look for a time with separation <= delta (G3).
      ContactRecord best, sample;
      bool have = false;
      const double mid = 0.5 * (task.s0 + task.s1);
      for (double s : {task.s0, mid, task.s1}) {
        // With no list (a dense region), ask the BVHs for the nearest
        // triangle within delta of the capsule instead.
        const bool got = requery
                             ? engine_.Separation(motion_, task.link, s, options_.delta_m, &sample)
                             : BestSample(task.link, s, begin, count, &sample);
        if (got && (!have || sample.separation < best.separation)) {
          best = sample;
          have = true;
        }
      }
      // Accept with the tolerance as margin, so that a checker reading the
      // files' decimal vertices (we hold floats) still sees <= delta; when
      // delta is within a few tolerances, plain <= delta (termination).
      const double accept =
          options_.delta_m > 4 * tol_ ? options_.delta_m - tol_ : options_.delta_m;
      if (have && best.separation <= accept) {
        FinishLeaf(task, best);
        if (!options_.per_link) break;
        continue;
      }
    }
    const double mid = 0.5 * (task.s0 + task.s1);
    if (!(mid > task.s0 && mid < task.s1) || task.depth >= 400) {
      FinishUndecided(task.link, task.s0);  // Cannot split further.
      if (!options_.per_link) break;
      continue;
    }
    // cap.a, cap.b is the segment at mid.
    queue_.push(Task{task.s0, mid, task.link, task.depth + 1, begin, count, requery, false, task.a0,
                     task.b0, cap.a, cap.b});
    queue_.push(Task{mid, task.s1, task.link, task.depth + 1, begin, count, requery, false, cap.a,
                     cap.b, task.a1, task.b1});
  }
  if (out_of_work) {
    // Every link with work left is undecided from its earliest open interval.
    std::vector<double> earliest(n, 2.0);
    while (!queue_.empty()) {
      const Task& t = queue_.top();
      if (!link_done_[t.link]) earliest[t.link] = std::min(earliest[t.link], t.s0);
      queue_.pop();
      if (!options_.per_link) break;  // The top one is the earliest of all.
    }
    for (int l = 0; l < n; ++l) {
      if (earliest[l] <= 1.0) FinishUndecided(l, earliest[l]);
    }
  }

  // Assemble the answer: the earliest bracket over all links.
  std::sort(result_.links.begin(), result_.links.end(),
            [](const LinkBracket& x, const LinkBracket& y) { return x.link < y.link; });
  const LinkBracket* first = nullptr;
  for (const LinkBracket& b : result_.links) {
    if (first == nullptr || b.s_lo < first->s_lo) first = &b;
  }
  if (first != nullptr) {
    result_.contact = true;
    result_.s_lo = first->s_lo;
    result_.s_hi = first->s_hi;
    result_.undecided = first->undecided;
    if (first->has_witness) result_.contacts.push_back(first->witness);
    // Other links' witnesses that fall inside the same bracket.
    for (const LinkBracket& b : result_.links) {
      if (&b != first && b.has_witness && b.witness.s >= result_.s_lo &&
          b.witness.s <= result_.s_hi && b.witness.separation <= options_.delta_m) {
        result_.contacts.push_back(b.witness);
      }
    }
    for (const LinkBracket& b : result_.links) {
      result_.initially_colliding = result_.initially_colliding || b.initially_colliding;
    }
    if (result_.s_lo == 0) {
      for (int l = 0; l < n && !result_.initially_colliding; ++l) {
        if (!filter_.IgnoresAll(l) && InitiallyTouching(l)) result_.initially_colliding = true;
      }
    }
  }
  if (!options_.per_link) result_.links.clear();
  return std::move(result_);
}

}  // namespace

CcdEngine::CcdEngine(const Skeleton& skeleton, const Environment& environment,
                     CollisionFilter filter)
    : skeleton_(skeleton), env_(environment), filter_(std::move(filter)) {}

QueryResult CcdEngine::Query(const Pose& pose0, const Pose& pose1,
                             const QueryOptions& options) const {
  SWEPTCCD_CHECK(pose1.utime > pose0.utime);
  SWEPTCCD_CHECK(ValidateQueryOptions(options).empty());
  QueryRun run(*this, pose0, pose1, options);
  return run.Run();
}

bool CcdEngine::TouchesAt(const PairMotion& motion, int link, double s, double slack) const {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion.SegmentAt(link, s, &a, &b);
  const double reach = skeleton_.link(link).radius + std::max(0.0, slack);
  bool touches = false;
  for (int o = 0; o < env_.num_objects() && !touches; ++o) {
    if (filter_.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env_.object(o).bvh;
    double search = reach;
    bvh.QueryCapsuleShrinking(a, b, &search, [&](uint32_t slot) {
      bvh.Triangle(slot, &ta, &tb, &tc);
      touches = SegmentTriangleDistance(a, b, ta, tb, tc).distance <= reach;
      return !touches;
    });
  }
  return touches;
}

bool CcdEngine::Separation(const PairMotion& motion, int link, double s, double search_radius,
                           ContactRecord* record) const {
  Eigen::Vector3d a, b, ta, tb, tc;
  motion.SegmentAt(link, s, &a, &b);
  const double radius = skeleton_.link(link).radius;
  const double reach = radius + std::max(0.0, search_radius);
  bool found = false;
  for (int o = 0; o < env_.num_objects(); ++o) {
    if (filter_.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env_.object(o).bvh;
    // Branch and bound: the search radius shrinks to the best distance so far.
    double search = found ? record->separation + radius : reach;
    bvh.QueryCapsuleShrinking(a, b, &search, [&](uint32_t slot) {
      bvh.Triangle(slot, &ta, &tb, &tc);
      const SegmentTriangleResult r = SegmentTriangleDistance(a, b, ta, tb, tc);
      if (r.distance > reach) return true;
      search = std::min(search, r.distance);
      const double sep = r.distance - radius;
      if (!found || sep < record->separation) {
        found = true;
        record->link = link;
        record->object = o;
        record->triangle = bvh.TriangleId(slot);
        record->s = s;
        record->point_link = r.p_segment;
        record->point_env = r.p_triangle;
        record->normal = UnitNormal(r, a, b, ta, tb, tc);
        record->separation = sep;
      }
      return r.distance > 0;  // Nothing is nearer than a crossing triangle.
    });
  }
  return found;
}

}  // namespace sweptccd
