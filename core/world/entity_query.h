#pragma once
// The entity query (SPEC section 8): the first time of contact between one
// avatar pair (A) and another entity (E) of a shared world - link against
// link of another avatar, or link against a tracked object's triangles -
// over the window where both exist, with the certificate of SPEC 6 (G1-G3)
// restricted to the two entities; and its record (EntityRecord, the
// counterpart of ResultRecord), which `sweptccd world` writes as JSON and
// the daemon as a shared_entry_t. Both call AnswerAgainstAvatar /
// AnswerAgainstObject over the same window (window_split.h) and the same
// entity views (entity_window.h), so live equals offline by construction.
//
// Time runs as tau, microseconds since the pair's utime0. Runs on the CPU
// only (every backend gives the same answers). The parts are internal:
// window_split (the window rule), entity_window (an entity's geometry and
// samples), interval_motions, avatar_target and object_target (what A's
// links are tested against), entity_broad_phase, entity_run (the descent
// as named phases).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/avatar/motion_memo.h"
#include "core/geometry/bvh.h"
#include "core/world/entity_window.h"
#include "core/world/window_split.h"
#include "core/world/world.h"

namespace sweptccd::world {

class IntervalMotions;

struct EntityQueryOptions {
  double eps_s = 1e-4;    // Bracket width, seconds (> 0).
  double delta_m = 1e-3;  // Distance tolerance of G3, metres (> 0).
  bool per_link = false;  // A bracket for every link of A that touches E.
  /// Work limit: items visited per (pair, entity). Past it: `undecided`.
  int64_t max_intervals = 2'000'000;
};

/// One witness between A and E, world frame.
struct OtherContact {
  LinkIndex link{0};      // A's link.
  LinkIndex other_link;   // E's link (avatar), else invalid (-1).
  int64_t triangle = -1;  // E's triangle id (object), else -1.
  double tau = 0;         // Microseconds since utime0.
  Eigen::Vector3d point_link{0, 0, 0}, point_other{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};  // Unit, from E's point towards A's.
  double separation = 0;
};

/// A bracket in tau (per link, or the answer's own).
struct OtherBracket {
  LinkIndex link;  // A's link.
  double tau_lo = 0, tau_hi = 0;
  bool initially_colliding = false;
  bool undecided = false;
  bool has_witness = false;
  OtherContact witness;
};

struct OtherAnswer {
  bool contact = false;
  OtherBracket bracket;             // When contact: the earliest bracket.
  std::vector<OtherBracket> links;  // Per-link mode: by link index.
  int64_t intervals = 0;            // Items visited.
  bool culled_by_box = false;       // The entity-level broad phase cleared it.
};

/// A's side of an entry: who it is (filters), its skeleton, the pair's
/// utimes, and what is kept across the pair's entries: the memo of the
/// pair's motion and, optionally, that motion's LinkSweepBoxes (extra 0;
/// else made per answer against an avatar).
struct PairSide {
  FilterSide who;
  const Skeleton& skeleton;
  int64_t utime0 = 0, utime1 = 0;
  MotionMemo* memo = nullptr;
  const std::vector<Aabb>* link_boxes = nullptr;
  /// Optionally, that motion's NearLinkBoxes (near_link_boxes.h) with
  /// margin NearMargin(options.delta_m) (else made per answer).
  const std::vector<Aabb>* near_link_boxes = nullptr;
};

/// A's pair against avatar `b` (against object `o`) over `window`, which
/// WindowOf made over E's samples. `scale` is WindowScale(E, pieces) (< 0:
/// computed here). Against an avatar, B's motions come from `motions` when
/// given (an IntervalMotions over `b`, kept across entries), else are made
/// here. Deterministic.
OtherAnswer AnswerAgainstAvatar(const PairSide& a, const AvatarWindow& b, const EntryWindow& window,
                                const EntityQueryOptions& options, double scale = -1,
                                IntervalMotions* motions = nullptr);
OtherAnswer AnswerAgainstObject(const PairSide& a, const ObjectWindow& o, const EntryWindow& window,
                                const EntityQueryOptions& options, double scale = -1);

/// A witness as reported: s = tau over the pair, clamped to [0, 1].
struct EntityContactRecord {
  LinkIndex link{0};
  LinkIndex other_link;   // An avatar's link, else invalid (-1).
  int64_t triangle = -1;  // An object's triangle id, else -1.
  double s = 0;
  Eigen::Vector3d point_link{0, 0, 0}, point_other{0, 0, 0}, normal{0, 0, 1};
  double separation = 0;
};

/// A bracket as reported: s rounded so that it never narrows the certified
/// bracket (s_lo down, s_hi up), t inside the window [t_from, t_to] (its
/// ends are exact integers).
struct EntityBracketRecord {
  LinkIndex link;
  bool initially_colliding = false, undecided = false;
  double s_lo = 0, s_hi = 0, t_lo = 0, t_hi = 0;
  bool has_witness = false;
  EntityContactRecord witness;
};

/// One entry (A's pair against E) as `sweptccd world` prints it and the
/// daemon publishes it.
struct EntityRecord {
  std::string entity;  // E's id.
  bool is_object = false;
  int64_t t_from = 0, t_to = 0;  // The window, utimes.
  bool contact = false;
  EntityBracketRecord bracket;                // When contact; else all zero / false.
  std::vector<EntityContactRecord> contacts;  // The bracket's witness, when it has one.
  bool per_link = false;
  std::vector<EntityBracketRecord> links;  // Per link (by link index), when per_link.
  int64_t intervals = 0;
  bool culled_by_box = false;
};

/// The record of `answer`, the entry of A's pair [utime0, utime1] against
/// E over [t_from, t_to]. Pure.
EntityRecord MakeEntityRecord(const std::string& entity, bool is_object, int64_t utime0,
                              int64_t utime1, int64_t t_from, int64_t t_to,
                              const OtherAnswer& answer, bool per_link);

/// The printed form of one bracket (as in EntityRecord).
EntityBracketRecord PrintBracket(const OtherBracket& b, int64_t utime0, int64_t utime1,
                                 int64_t t_from, int64_t t_to);

}  // namespace sweptccd::world
