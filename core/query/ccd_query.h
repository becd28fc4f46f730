#pragma once
// The continuous collision query of SPEC section 6: the first time an
// articulated avatar moving between two poses touches a static environment.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/query/capsule_culler.h"
#include "core/query/pair_clears.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/typed_index.h"

namespace sweptccd {

struct QueryOptions {
  MotionModel motion = MotionModel::kArticulated;
  double eps_s = 1e-4;    // Time tolerance: bracket width, seconds (> 0).
  double delta_m = 1e-3;  // Distance tolerance for G3, metres (> 0).
  bool per_link = false;  // A bracket for every link that touches.
  /// Work limit: interval tests per query. Past it the query answers
  /// `contact` with `undecided` (G1 still holds).
  int64_t max_intervals = 2'000'000;
  /// Candidate triangles a time interval keeps as a list for its halves; past
  /// it the halves query the BVH again. Small on purpose: a half's capsule is
  /// usually far thinner than its parent's, and the BVH's node boxes refuse
  /// most of a long list in groups, where refining the list tests every
  /// triangle (docs/BENCHMARKS.md, "Short candidate lists").
  int max_candidates = 8;
  /// Hierarchical link bounds (`articulated` only; core/query/link_groups.h):
  /// a subtree of at least 4 links (a hand, a finger, a foot) is first
  /// tested as one ball around its root; when the ball meets nothing its
  /// links are culled without composing their poses. The answers are the
  /// same either way (tested); false tests every link on its own (the
  /// full-body benchmark's baseline).
  bool link_groups = true;
  /// The groups are tried only on skeletons of at least this many links. On
  /// the 16-link bodies they cost more than they save (4.5 % more
  /// instructions in `bench`, tools/bench_callgrind.sh, 2026-11-28): their
  /// subtrees are an arm's few links, which the BVH culls one by one as
  /// cheaply. 0: on every skeleton (the tests that compare both ways).
  int link_groups_min_links = 32;
  /// Groups of fewer links (a finger's, a foot's) are not tested: their
  /// links' loose capsules (docs/DESIGN.md, "Loose capsules") cost less than
  /// the ball's test on the bundled rooms. The answer is the same for any
  /// value (tested with 0 too).
  int link_group_min_size = 8;
};

/// Empty when the options are usable, else the problem (names the option).
std::string ValidateQueryOptions(const QueryOptions& options);

/// One witness: where a link is closest to (or inside) the environment.
struct ContactRecord {
  LinkIndex link;
  ObjectIndex object;
  uint32_t triangle = 0;  // Index within the object, file order after the fan split.
  double s = 0;
  Eigen::Vector3d point_link{0, 0, 0};  // On the link's segment, world frame.
  Eigen::Vector3d point_env{0, 0, 0};   // On the triangle, world frame.
  Eigen::Vector3d normal{0, 0, 1};      // Unit, from the environment towards the link.
  double separation = 0;                // Distance minus radius, metres.
};

/// A bracket for one link (per-link mode), with G1-G3 for that link alone.
struct LinkBracket {
  LinkIndex link;
  double s_lo = 0, s_hi = 0;
  bool initially_colliding = false;
  bool undecided = false;
  bool has_witness = false;
  ContactRecord witness;
};

struct QueryStats {
  int links_tested = 0;    // Links whose swept bound met the environment.
  int links_culled = 0;    // Links the link BVH cleared for the whole pair.
  int groups_cleared = 0;  // Link groups whose ball met nothing (their links are culled).
  int loose_cleared = 0;   // Other links whose loose capsule met nothing (culled, never composed).
  int64_t intervals = 0;   // Time intervals tested.
  int64_t triangle_tests = 0;
  // With a culler (the GPU backend): round trips, capsules sent, and
  // intervals it cleared (the CPU did not test those).
  int64_t cull_round_trips = 0;
  int64_t cull_capsules = 0;
  int64_t cull_cleared = 0;
};

struct QueryResult {
  bool contact = false;  // false: `free`.
  bool initially_colliding = false;
  bool undecided = false;
  double s_lo = 0, s_hi = 0;            // Meaningful when contact.
  std::vector<ContactRecord> contacts;  // At least one when contact and decided.
  std::vector<LinkBracket> links;       // Per-link mode: every touching link, by index.
  QueryStats stats;
};

/// Duration of a pair in microseconds, without int64 overflow.
double PairDurationUs(int64_t utime0, int64_t utime1);
/// The time (microseconds) of s in the pair, rounded down: printed as t_lo it
/// is never later than the certified s_lo.
double BracketTimeLo(int64_t utime0, int64_t utime1, double s);
/// The time of s rounded up (for t_hi).
double BracketTimeHi(int64_t utime0, int64_t utime1, double s);

/// Answers queries for one skeleton against one environment (the engine's
/// parts are mapped in docs/DESIGN.md, "core/query"). Holds references:
/// the skeleton and environment must outlive it. Query is const and
/// thread-safe (each call uses its own scratch memory).
namespace internal {
class LinkGroups;
}  // namespace internal

class CcdEngine {
 public:
  CcdEngine(const Skeleton& skeleton, const Environment& environment,
            CollisionFilter filter = CollisionFilter());

  /// Hands the swept-volume tests to `culler` (the GPU backend) first: an
  /// interval it clears is free without a CPU test; the CPU decides the rest
  /// exactly as without it, so brackets are the same. Set before queries
  /// start (not thread-safe against Query); nullptr: CPU only.
  void SetCuller(std::shared_ptr<const CapsuleCuller> culler) { culler_ = std::move(culler); }
  const CapsuleCuller* culler() const { return culler_.get(); }

  /// Preconditions: both poses valid (ValidateAndNormalizePose) and
  /// pose1.utime > pose0.utime; options valid (ValidateQueryOptions).
  QueryResult Query(const Pose& pose0, const Pose& pose1, const QueryOptions& options) const;
  /// The same, given the pair's motion, which callers that need it too (the
  /// shared world's parts) build once: PairMotion(skeleton, pose0, pose1,
  /// options.motion) of this engine's skeleton. The same answer.
  QueryResult Query(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                    const QueryOptions& options) const;
  /// The same, skipping the intervals `clears` holds (the device descent,
  /// docs/GPU.md: each is one this query's own test would clear, so the
  /// answer is the same; stats.cull_cleared counts those skipped). nullptr:
  /// as Query above.
  QueryResult Query(const Pose& pose0, const Pose& pose1, const QueryOptions& options,
                    const PairClears* clears) const;
  /// Both: the pair's motion given, and the intervals `clears` holds skipped
  /// (the shared world's environment parts through the device descent).
  QueryResult Query(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                    const QueryOptions& options, const PairClears* clears) const;

  /// Exact separation of `link` at s (distance to the nearest unfiltered
  /// triangle minus the radius), searching only within `search_radius` of the
  /// capsule surface; returns false when nothing is that close.
  bool Separation(const PairMotion& motion, LinkIndex link, double s, double search_radius,
                  ContactRecord* record) const;

  /// Whether `link` touches (separation <= `slack`, metres) at s. Stops at the
  /// first triangle found, so it is cheaper than Separation.
  bool TouchesAt(const PairMotion& motion, LinkIndex link, double s, double slack) const;

  const Skeleton& skeleton() const { return skeleton_; }
  const Environment& environment() const { return env_; }
  const CollisionFilter& filter() const { return filter_; }
  /// The skeleton's link groups (core/query/link_groups.h), built once.
  const internal::LinkGroups& link_groups() const { return *groups_; }

 private:
  const Skeleton& skeleton_;
  const Environment& env_;
  CollisionFilter filter_;
  std::shared_ptr<const CapsuleCuller> culler_;
  std::shared_ptr<const internal::LinkGroups> groups_;
};

}  // namespace sweptccd
