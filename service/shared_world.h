#pragma once
// The shared world of the live service (SPEC section 8, "Live";
// docs/SERVICE.md "Shared world"): every entity's recent samples (a bounded
// history) and the bounded pending list of (avatar pair, other entity)
// entries that wait until that entity's samples cover the pair's window, or
// until it has been silent for the one silence timeout. Transport-free and
// single-threaded (CollisionService serialises every call under its mutex);
// the geometry of a due entry runs later, off the lock, in AnswerSharedJob.
//
// Time base: every utime (tracker_pose_t, object_pose_t) is taken as sent,
// on the one time base all clients share (SPEC 8 offline: as written in the
// files); the daemon maps nothing. Waiting and silence are measured on the
// daemon's steady clock, from the receipt of messages.
//
// Equality with `sweptccd world`: an entry answered because the entity
// covered the window (a sample at or after the pair's utime1; after it for a
// window of one instant, Covered) is given
// exactly the samples the offline answer uses and is answered by the same
// code: the window rule (core/world/window_split.h), the broad phase
// (EntryNear), the entity query and its record (core/world/entity_query.h),
// so it is bit-equal to the offline entry on the same samples. Entries ended by the timeout, or whose window starts before the
// entity's oldest kept sample (history cut), say ended_by_timeout.

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/scene/environment.h"
#include "core/world/entity_query.h"
#include "core/world/world.h"
#include "service/client_session.h"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/shared_contact_t.hpp"

namespace sweptccd {

struct SharedWorldOptions {
  /// The one silence timeout (ServiceConfig::silence_timeout_ms), > 0: an
  /// entity silent this long ends the windows waiting for it at its last
  /// sample; an entry that waited this long is cut the same way.
  int64_t silence_timeout_us = 5'000'000;
  /// Samples kept per entity (>= 2), entries pending in all (>= 1). A full
  /// pending list cuts its oldest entry.
  int max_history = 4096;
  int max_pending = 4096;
  /// The broad phase (SharedJob::cleared_by_box). Off only to test that the
  /// entries it clears are those the full answer finds `free`.
  bool broad_phase = true;
};

/// What an avatar's own configuration changes in the answers of the shared
/// world (ClientConfig).
struct AvatarAnswerOptions {
  double eps_s = 0, delta_m = 0;         // Its tolerances; 0: the service's.
  std::vector<world::EntityRule> rules;  // Its filters (SPEC 8), resolved.
};

/// One (pair of avatar A, other entity E) entry, due: everything its answer
/// needs, copied out of the shared world (the samples of E the window uses,
/// re-based: its first is the last one at or before t_from).
struct SharedJob {
  std::string client_id;  // A.
  int64_t pair = 0, seq0 = 0, seq1 = 0;
  int64_t receive_utime = 0;  // When A's pose seq1 was received (service clock).
  std::shared_ptr<const Skeleton> skeleton_a;
  MotionModel motion_a = MotionModel::kArticulated;
  /// A's motion over the pair, built once for all the pair's entries (null
  /// in a job made outside SharedWorld: then built by AnswerSharedJob).
  std::shared_ptr<const PairMotion> pair_motion;
  /// A's and E's (an avatar's) own options: A's tolerances answer the
  /// entry, and a filter rule of either applies to the pair of links
  /// (SPEC 8 "Filters"). Null: none (the service's tolerances, no rule).
  std::shared_ptr<const AvatarAnswerOptions> own_a, own_e;
  Pose pose0, pose1;
  std::string entity;  // E's id.
  bool entity_is_object = false;
  std::shared_ptr<const Skeleton> skeleton_e;  // E an avatar.
  MotionModel motion_e = MotionModel::kArticulated;
  std::vector<Pose> avatar_samples;                // E an avatar: the slice.
  std::shared_ptr<const Environment> mesh_e;       // E an object: its mesh (one object).
  std::vector<world::RigidSample> object_samples;  // E an object: the slice.
  int64_t t_from = 0, t_to = 0;                    // The window, utimes.
  int64_t waited_us = 0;
  bool ended_by_timeout = false;
  /// When it became due (MakeJob): shared_entry_t.queue_us runs from here.
  SteadyClock::time_point due_time;
  /// The broad phase of `sweptccd world` (WorldAnswerer::AnswerEntity)
  /// cleared it: A's box over the pair is apart from E's box of every
  /// interval the window uses, so the entry is `free` with no link work.
  /// Such a job carries no samples, and of pose0 and pose1 only the utimes.
  bool cleared_by_box = false;
};

/// Answers one due entry through the entity query of `sweptccd world`
/// (core/world/entity_query.h, over the job's slice): one entry of a shared_contact_t, with
/// per-link brackets when options.per_link. A's tolerances (job.own_a)
/// replace options' where set: A's record is answered to A's
/// tolerances, as its environment part is. Pure and deterministic (but for
/// compute_us); any thread. A job cleared_by_box is answered `free` at
/// once, as `sweptccd world` answers it. Never throws (a failure is
/// RESULT_INVALID with `error`).
shared_entry_t AnswerSharedJob(const SharedJob& job, const world::EntityQueryOptions& options);

/// The message that carries the entries of `job`'s pair: the pair's fields
/// set, no entries yet, utime and mac unset. Any thread.
shared_contact_t SharedMessageOf(const SharedJob& job);

class SharedWorld {
 public:
  using Time = SteadyClock::time_point;

  /// Throws InputError on options out of range.
  explicit SharedWorld(SharedWorldOptions options);

  /// Registers an avatar (a configured client, or a live client on join)
  /// with what its own configuration changes in the answers: its tolerances
  /// (they answer the entries of its own pairs) and its filters.
  /// Precondition: the id is not registered; tolerances >= 0.
  void AddAvatar(const std::string& id, std::shared_ptr<const Skeleton> skeleton,
                 MotionModel motion, Time now, const AvatarAnswerOptions& own = {});
  /// Registers a tracked object (configured only). Precondition: the id is
  /// not registered; `mesh` holds one object.
  void AddObject(const std::string& id, std::shared_ptr<const Environment> mesh, Time now);
  /// An avatar that left or expired: every entry waiting for it is cut now
  /// (appended to *due), its own pending entries are dropped unanswered (its
  /// pairs' shared parts go with it), then it is gone.
  void RemoveAvatar(const std::string& id, Time now, std::vector<SharedJob>* due);
  bool Has(const std::string& id) const { return entities_.count(id) > 0; }

  /// A pose the avatar's ClientSession accepted (session: its stream). A new
  /// session drops the history (and cuts the entries waiting for it first).
  /// Entries this sample covers go to *due.
  void OnAvatarSample(const std::string& id, int64_t session, const Pose& pose, Time now,
                      std::vector<SharedJob>* due);

  /// An object pose from the wire (bytes, id rule and mac already checked):
  /// nullopt when used, else why not: unknown_object (no such configured
  /// object), non_finite / position_out_of_range / zero_quaternion,
  /// stale_session, non_increasing_seq, non_increasing_utime, utime_jump
  /// (`max_utime_jump_us`). Entries it covers go to *due.
  std::optional<Rejection> OnObjectPose(const object_pose_t& msg, int64_t max_utime_jump_us,
                                        Time now, std::vector<SharedJob>* due);

  /// A's pair, as handed to a worker for its environment part: one entry per
  /// other registered entity; those already covered (or silent) go to *due at
  /// once, the rest wait. `receive_time`: A's pose seq1 was received.
  void AddPair(const std::string& id, const PosePair& pair, Time now, std::vector<SharedJob>* due);

  /// Cuts every entry whose entity was silent, or that itself waited, for
  /// silence_timeout_us before `now`. The service calls it on the daemon's
  /// silence timer (8 times per timeout, CollisionService::ExpireSilent), so
  /// a cut comes between 1 and 9/8 of the timeout. O(entities + pending).
  void CutSilent(Time now, std::vector<SharedJob>* due);
  /// Cuts everything still pending (the service is stopping).
  void CutAll(Time now, std::vector<SharedJob>* due);

  size_t pending() const;  // Entries waiting, over every entity.
  /// Entries made ended_by_timeout (silence, a new stream, a removed
  /// avatar, the history cut, stopping), and of those the ones cut early
  /// because more than max_pending waited.
  int64_t entries_cut() const { return entries_cut_; }
  int64_t entries_overflowed() const { return entries_overflowed_; }
  /// Entries the broad phase cleared (jobs made cleared_by_box).
  int64_t entries_cleared() const { return entries_cleared_; }
  int64_t history_size(const std::string& id) const;

 private:
  struct SharedPair : PosePair {
    Aabb box_a;                                // A over the pair (AvatarMotionBox).
    std::shared_ptr<const PairMotion> motion;  // A's over the pair, for every entry.
  };
  struct Entry {
    std::string a;  // The avatar whose pair it is.
    std::shared_ptr<const Skeleton> skeleton_a;
    MotionModel motion_a = MotionModel::kArticulated;
    std::shared_ptr<const AvatarAnswerOptions> own_a;
    std::shared_ptr<const SharedPair> pair;  // Shared by the pair's entries.
    Time created;
    uint64_t number = 0;  // Creation order over every entity's entries.
  };

  struct Entity {
    std::string id;
    bool is_object = false;
    std::shared_ptr<const Skeleton> skeleton;
    MotionModel motion = MotionModel::kArticulated;
    std::shared_ptr<const AvatarAnswerOptions> own;  // An avatar's (AddAvatar).
    std::shared_ptr<const Environment> mesh;
    bool has_stream = false;
    int64_t session = 0, last_seq = 0;
    std::deque<Pose> avatar_samples;  // Strictly increasing utimes.
    std::deque<world::RigidSample> object_samples;
    // boxes[k]: the entity over its samples k -> k+1 (AvatarMotionBox or
    // ObjectMotionBox, as WorldAnswerer makes them), made once when sample
    // k+1 arrives so that an entry costs box tests only; one fewer than
    // the samples, evicted and cleared with them.
    std::deque<Aabb> boxes;
    // An avatar: its motion over its last two samples (made with their
    // box), which the pair they close answers every entry with.
    std::shared_ptr<const PairMotion> last_motion;
    double radius = 0, mesh_scale = 0;  // An object: ObjectRadius, its BVH's scale.
    bool evicted = false;               // The history dropped older samples of this stream.
    Time last_heard;                    // Registration, then every used sample.
    Time last_sample_time;              // Receipt of the newest sample.
    // The entries waiting for this entity's samples, oldest first: a sample
    // looks at its own entity's entries only, not at every pending entry.
    std::deque<Entry> pending;
    size_t size() const { return is_object ? object_samples.size() : avatar_samples.size(); }
    int64_t utime(size_t k) const {
      return is_object ? object_samples[k].utime : avatar_samples[k].utime;
    }
  };
  // E's box over its samples k0 -> k1 (k1 == k0 for a one-sample entity);
  // an avatar's motion over them in *motion when given.
  static Aabb IntervalBox(const Entity& e, size_t k0, size_t k1,
                          std::shared_ptr<const PairMotion>* motion = nullptr);

  // Whether entry's window is settled by E's samples now (covered).
  static bool Covered(const Entity& e, const Entry& entry);
  // Makes the job of an entry against E (covered: exact; else cut at E's
  // last sample). False when the window is empty (no job).
  bool MakeJob(const Entity& e, const Entry& entry, bool cut, Time now, SharedJob* job) const;
  // Makes entry's job against E (MakeJob), counts it, appends it to `due`.
  void SettleOne(const Entity& e, const Entry& entry, bool cut, Time now,
                 std::vector<SharedJob>* due);
  // Settles every pending entry of E that `pred` says; appends jobs.
  template <class Pred>
  void Settle(const std::string& e, Pred pred, bool cut, Time now, std::vector<SharedJob>* due);
  void Append(Entity* e, Time now);  // Evicts beyond max_history.

  SharedWorldOptions options_;
  std::map<std::string, Entity> entities_;
  std::vector<std::string> order_;  // Registration order (avatars and objects).
  uint64_t next_entry_number_ = 0;
  int64_t entries_cut_ = 0;
  int64_t entries_overflowed_ = 0;
  int64_t entries_cleared_ = 0;
};

}  // namespace sweptccd
