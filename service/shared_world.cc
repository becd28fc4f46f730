#include "service/shared_world.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <utility>

#include "core/errors.h"
#include "core/query/ccd_query.h"
#include "core/query/result_json.h"

namespace sweptccd {

namespace {

int64_t MicrosSince(SteadyClock::time_point from, SteadyClock::time_point to) {
  return std::max<int64_t>(
      0, std::chrono::duration_cast<std::chrono::microseconds>(to - from).count());
}

void Put3(const Eigen::Vector3d& v, double out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = v[k];
}

entity_contact_t ContactOf(const world::OtherContact& c, double dur) {
  entity_contact_t out;
  out.link = c.link;
  out.other_link = c.other_link;
  out.triangle = c.triangle;
  out.s = std::clamp(c.tau / dur, 0.0, 1.0);
  Put3(c.point_link, out.point_link);
  Put3(c.point_other, out.point_other);
  Put3(c.normal, out.normal);
  out.separation = c.separation;
  return out;
}

// The bracket fields an entry and a per-link bracket share, as printed.
template <typename Msg>
void PutBracket(const world::OtherBracket& b, const SharedJob& job, Msg* out) {
  const world::PrintedBracket p =
      world::PrintBracket(b, job.pose0.utime, job.pose1.utime, job.t_from, job.t_to);
  out->s_lo = p.s_lo;
  out->s_hi = p.s_hi;
  out->t_lo = p.t_lo;
  out->t_hi = p.t_hi;
  out->initially_colliding = b.initially_colliding;
  out->undecided = b.undecided;
}

entity_link_bracket_t LinkBracketOf(const world::OtherBracket& b, const SharedJob& job,
                                    double dur) {
  entity_link_bracket_t out{};
  out.link = b.link;
  PutBracket(b, job, &out);
  out.has_witness = b.has_witness;
  if (b.has_witness) out.witness = ContactOf(b.witness, dur);
  return out;
}

// An entry naming the job's entity and window, its result `free`.
shared_entry_t EntryOf(const SharedJob& job) {
  shared_entry_t m{};
  m.entity = job.entity;
  m.entity_kind =
      job.entity_is_object ? shared_entry_t::KIND_OBJECT : shared_entry_t::KIND_AVATAR;
  m.t_from = job.t_from;
  m.t_to = job.t_to;
  m.result = shared_entry_t::RESULT_FREE;
  m.waited_us = job.waited_us;
  m.ended_by_timeout = job.ended_by_timeout;
  return m;
}

}  // namespace

shared_entry_t AnswerSharedJob(const SharedJob& job, const world::EntityQueryOptions& given) {
  world::EntityQueryOptions options = given;
  if (job.own_a && job.own_a->eps_s > 0) options.eps_s = job.own_a->eps_s;
  if (job.own_a && job.own_a->delta_m > 0) options.delta_m = job.own_a->delta_m;
  shared_entry_t m = EntryOf(job);
  const auto start = SteadyClock::now();
  // A job made outside SharedWorld (tests) has no due time: no wait.
  const double queue_us =
      job.due_time == SteadyClock::time_point{}
          ? 0.0
          : std::chrono::duration<double, std::micro>(start - job.due_time).count();
  if (job.cleared_by_box) {
    m.compute_us = std::chrono::duration<double, std::micro>(SteadyClock::now() - start).count();
    m.queue_us = queue_us;
    return m;
  }
  try {
    // A two-entity world: A (its pair) and E (the slice of its history the
    // window uses). Index 0 is A; E is avatar 1 or object 0.
    world::World w;
    world::AvatarEntity a;
    a.id = job.client_id;
    a.skeleton = *job.skeleton_a;
    a.motion = job.motion_a;
    a.used = {job.pose0, job.pose1};
    w.avatars.push_back(std::move(a));
    std::vector<int64_t> times;
    if (job.entity_is_object) {
      world::ObjectEntity o;
      o.id = job.entity;
      o.mesh = job.mesh_e;
      o.used = job.object_samples;
      for (const world::RigidSample& x : o.used) times.push_back(x.utime);
      w.objects.push_back(std::move(o));
    } else {
      world::AvatarEntity e;
      e.id = job.entity;
      e.skeleton = *job.skeleton_e;
      e.motion = job.motion_e;
      e.used = job.avatar_samples;
      for (const Pose& p : e.used) times.push_back(p.utime);
      w.avatars.push_back(std::move(e));
    }
    w.rules.assign(w.avatars.size(), {});
    if (job.own_a) w.rules[0] = job.own_a->rules;
    if (job.own_e && !job.entity_is_object) w.rules[1] = job.own_e->rules;
    const int64_t u0 = job.pose0.utime, u1 = job.pose1.utime;
    const std::vector<world::Piece> pieces = world::SplitWindow(u0, job.t_from, job.t_to, times);
    const PairMotion motion(w.avatars[0].skeleton, job.pose0, job.pose1, job.motion_a);
    const std::unique_ptr<world::OtherTarget> target =
        job.entity_is_object
            ? world::MakeObjectTarget(w, 0, 0, world::WindowScale(w.objects[0], pieces))
            : world::MakeAvatarTarget(w, 0, 1, world::WindowScale(w.avatars[1], pieces));
    const world::OtherAnswer ans =
        world::AnswerOther(w.avatars[0].skeleton, motion, u0, u1, pieces, *target, options);
    const double dur = static_cast<double>(u1 - u0);
    if (ans.contact) {
      const world::OtherBracket& b = ans.bracket;
      m.result = shared_entry_t::RESULT_CONTACT;
      PutBracket(b, job, &m);
      if (b.has_witness) m.contacts.push_back(ContactOf(b.witness, dur));
      m.num_contacts = static_cast<int32_t>(m.contacts.size());
    }
    if (options.per_link) {
      for (const world::OtherBracket& b : ans.links) m.links.push_back(LinkBracketOf(b, job, dur));
      m.num_links = static_cast<int32_t>(m.links.size());
    }
  } catch (const std::exception& e) {
    m = EntryOf(job);
    m.result = shared_entry_t::RESULT_INVALID;
    m.error = std::string("query failed: ") + e.what();
  }
  m.compute_us = std::chrono::duration<double, std::micro>(SteadyClock::now() - start).count();
  m.queue_us = queue_us;
  return m;
}

shared_contact_t SharedMessageOf(const SharedJob& job) {
  shared_contact_t m{};
  m.client_id = job.client_id;
  m.seq0 = job.seq0;
  m.seq1 = job.seq1;
  m.pair = job.pair;
  m.utime0 = job.pose0.utime;
  m.utime1 = job.pose1.utime;
  m.receive_utime = job.receive_utime;
  m.num_entries = 0;
  return m;
}

SharedWorld::SharedWorld(SharedWorldOptions options) : options_(options) {
  if (options_.silence_timeout_us < 1 || options_.max_history < 2 || options_.max_pending < 1) {
    throw InputError(
        "shared world: silence_timeout_us must be >= 1, max_history >= 2 and "
        "max_pending >= 1");
  }
}

void SharedWorld::AddAvatar(const std::string& id, std::shared_ptr<const Skeleton> skeleton,
                            MotionModel motion, Time now, const AvatarAnswerOptions& own) {
  SWEPTCCD_CHECK(!Has(id) && skeleton && own.eps_s >= 0 && own.delta_m >= 0);
  Entity e;
  e.id = id;
  e.skeleton = std::move(skeleton);
  e.motion = motion;
  e.own = std::make_shared<const AvatarAnswerOptions>(own);
  e.last_heard = now;
  e.last_sample_time = now;
  entities_.emplace(id, std::move(e));
  order_.push_back(id);
}

void SharedWorld::AddObject(const std::string& id, std::shared_ptr<const Environment> mesh,
                            Time now) {
  SWEPTCCD_CHECK(!Has(id) && mesh && mesh->num_objects() == 1);
  Entity e;
  e.id = id;
  e.is_object = true;
  e.mesh = std::move(mesh);
  const TriangleBvh& bvh = e.mesh->object(0).bvh;
  e.radius = world::ObjectRadius(bvh);
  e.mesh_scale = bvh.max_abs_coordinate();
  e.last_heard = now;
  e.last_sample_time = now;
  entities_.emplace(id, std::move(e));
  order_.push_back(id);
}

void SharedWorld::RemoveAvatar(const std::string& id, Time now, std::vector<SharedJob>* due) {
  if (!Has(id)) return;
  Settle(
      id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
  for (auto& [other, e] : entities_) {
    e.pending.erase(std::remove_if(e.pending.begin(), e.pending.end(),
                                   [&](const Entry& x) { return x.a == id; }),
                    e.pending.end());
  }
  entities_.erase(id);
  order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
}

size_t SharedWorld::pending() const {
  size_t n = 0;
  for (const auto& [id, e] : entities_) n += e.pending.size();
  return n;
}

int64_t SharedWorld::history_size(const std::string& id) const {
  const auto it = entities_.find(id);
  return it == entities_.end() ? 0 : static_cast<int64_t>(it->second.size());
}

Aabb SharedWorld::IntervalBox(const Entity& e, size_t k0, size_t k1) {
  if (e.is_object) {
    return world::ObjectMotionBox(e.object_samples[k0], e.object_samples[k1], e.radius,
                                  e.mesh_scale);
  }
  return world::AvatarMotionBox(
      *e.skeleton, PairMotion(*e.skeleton, e.avatar_samples[k0], e.avatar_samples[k1], e.motion));
}

void SharedWorld::Append(Entity* e, Time now) {
  // The new sample closes an interval: its box, on the receiving thread,
  // once, rather than once per entry that uses it.
  if (e->size() >= 2) e->boxes.push_back(IntervalBox(*e, e->size() - 2, e->size() - 1));
  e->last_heard = now;
  e->last_sample_time = now;
  while (static_cast<int>(e->size()) > options_.max_history) {
    if (e->is_object) {
      e->object_samples.pop_front();
    } else {
      e->avatar_samples.pop_front();
    }
    e->boxes.pop_front();  // One fewer than the samples, so one is there.
    e->evicted = true;
  }
}

void SharedWorld::OnAvatarSample(const std::string& id, int64_t session, const Pose& pose, Time now,
                                 std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end()) return;
  Entity& e = it->second;
  if (e.has_stream && session != e.session) {
    // A new stream: what waited for the old one ends at its last sample.
    Settle(
        id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
    e.avatar_samples.clear();
    e.boxes.clear();
    e.evicted = false;
  }
  e.has_stream = true;
  e.session = session;
  // ClientSession accepted it: strictly after the last sample of the stream.
  SWEPTCCD_CHECK(e.avatar_samples.empty() || pose.utime > e.avatar_samples.back().utime);
  e.avatar_samples.push_back(pose);
  Append(&e, now);
  Settle(
      id, [&](const Entry& x) { return Covered(e, x); }, /*cut=*/false, now, due);
}

std::optional<Rejection> SharedWorld::OnObjectPose(const object_pose_t& msg,
                                                   int64_t max_utime_jump_us, Time now,
                                                   std::vector<SharedJob>* due) {
  const auto it = entities_.find(msg.object_id);
  if (it == entities_.end() || !it->second.is_object) {
    return Rejection{rejection_code::kUnknownObject,
                     "object_id '" + msg.object_id +
                         "' is not a tracked object of this daemon; configure it under "
                         "`objects:` (id, mesh, key)"};
  }
  Entity& e = it->second;
  double v[7];
  for (int k = 0; k < 3; ++k) v[k] = msg.position[k];
  for (int k = 0; k < 4; ++k) v[3 + k] = msg.orientation[k];
  world::RigidSample x;
  const std::string problem = world::MakeRigidSample(msg.utime, v, &x);
  if (!problem.empty()) {
    const char* code = problem.find("finite") != std::string::npos ? rejection_code::kNonFinite
                       : problem.find("position") != std::string::npos
                           ? rejection_code::kPositionOutOfRange
                           : rejection_code::kZeroQuaternion;
    return Rejection{code, "object '" + msg.object_id + "' seq " + std::to_string(msg.seq) + ": " +
                               problem + "; send a finite pose with a unit quaternion"};
  }
  const bool new_stream = !e.has_stream || msg.session > e.session;
  if (!new_stream) {
    if (msg.session < e.session) {
      return Rejection{rejection_code::kStaleSession,
                       "object '" + msg.object_id + "' session " + std::to_string(msg.session) +
                           " is older than its current session " + std::to_string(e.session) +
                           "; a restarted tracker takes a greater session"};
    }
    if (msg.seq <= e.last_seq) {
      return Rejection{rejection_code::kNonIncreasingSeq,
                       "object '" + msg.object_id + "' seq " + std::to_string(msg.seq) +
                           " is not greater than " + std::to_string(e.last_seq) +
                           "; number samples strictly increasingly"};
    }
    const int64_t last = e.object_samples.empty() ? msg.utime - 1 : e.object_samples.back().utime;
    if (msg.utime <= last) {
      return Rejection{rejection_code::kNonIncreasingUtime,
                       "object '" + msg.object_id + "' utime " + std::to_string(msg.utime) +
                           " is not after " + std::to_string(last) +
                           "; stamp samples strictly increasingly"};
    }
    if (msg.utime - last > max_utime_jump_us) {
      return Rejection{rejection_code::kUtimeJump,
                       "object '" + msg.object_id + "' utime " + std::to_string(msg.utime) +
                           " is more than max_utime_jump_s after " + std::to_string(last) +
                           "; fix the tracker's clock, or start a new session"};
    }
  }
  if (new_stream && e.has_stream) {
    Settle(
        msg.object_id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
    e.object_samples.clear();
    e.boxes.clear();
    e.evicted = false;
  }
  e.has_stream = true;
  e.session = msg.session;
  e.last_seq = msg.seq;
  e.object_samples.push_back(x);
  Append(&e, now);
  Settle(
      msg.object_id, [&](const Entry& y) { return Covered(e, y); }, /*cut=*/false, now, due);
  return std::nullopt;
}

bool SharedWorld::Covered(const Entity& e, const Entry& entry) {
  // The window [t_from, utime1] and every sample the offline answer uses for
  // it are in once E has a sample at or after utime1: SplitWindow's pieces
  // end with E's interval into its first sample at or after t_to, and skip
  // that sample's instant (a boundary instant of a longer window), so
  // nothing after it is read. So a sample stamped at utime1 itself covers
  // (trackers that stamp every body at the same frame times get their
  // shared answer in that frame, not the next), except for a window that is
  // one instant (E's first sample at utime1): its one piece lies in E's
  // interval after that sample, which needs the next sample.
  if (e.size() == 0) return false;
  const int64_t newest = e.utime(e.size() - 1), u1 = entry.pair->pose1.utime;
  if (newest > u1) return true;
  return newest == u1 && std::max(entry.pair->pose0.utime, e.utime(0)) < u1;
}

bool SharedWorld::Near(const Entity& e, const Aabb& box_a, size_t first, int64_t t_from,
                       int64_t t_to) {
  const size_t n = e.size();
  if (n == 1) return box_a.Overlaps(IntervalBox(e, 0, 0));
  // The intervals of SplitWindow's pieces, walked in place over the deque
  // (no times vector, no pieces) by the same rule: from `first`, skipping a
  // boundary instant of a longer window; one piece for an instant window.
  for (size_t k = first; k + 1 < n && e.utime(k) <= t_to; ++k) {
    const int64_t lo = std::max(t_from, e.utime(k));
    const int64_t hi = std::min(t_to, e.utime(k + 1));
    if (lo > hi) continue;
    if (lo == hi && t_from < t_to) continue;
    if (box_a.Overlaps(e.boxes[k])) return true;
    if (t_from == t_to) break;
  }
  return false;
}

bool SharedWorld::MakeJob(const Entity& e, const Entry& entry, bool cut, Time now,
                          SharedJob* job) const {
  const size_t n = e.size();
  if (n == 0) return false;
  const int64_t u0 = entry.pair->pose0.utime, u1 = entry.pair->pose1.utime;
  const int64_t t_from = std::max(u0, e.utime(0));
  const int64_t t_to = std::min(u1, e.utime(n - 1));
  if (t_from > t_to) return false;  // No overlap: no entry (as offline).
  // f: the last sample at or before t_from; l: the first at or after t_to
  // (else the last). Binary searches: this runs per entry on the service's
  // lock, and a history holds up to max_history samples.
  const auto count_before = [&](int64_t t, bool or_at) {  // Samples before t (or at).
    size_t lo = 0, hi = n;
    while (lo < hi) {
      const size_t mid = lo + (hi - lo) / 2;
      if (e.utime(mid) < t || (or_at && e.utime(mid) == t)) {
        lo = mid + 1;
      } else {
        hi = mid;
      }
    }
    return lo;
  };
  size_t f = count_before(t_from, true) - 1;  // utime(0) <= t_from: at least one.
  size_t l = std::max(f, std::min(count_before(t_to, false), n - 1));
  if (n >= 2) {
    // SplitWindow's pieces use samples k and k+1 (k clamped to n - 2).
    if (f == n - 1) --f;
    if (l == f) ++l;
  }
  // f is SplitWindow's first interval. Pieces over the slice from f are E's
  // intervals f + k, whose boxes are those of the whole history.
  job->cleared_by_box = options_.broad_phase && !Near(e, entry.pair->box_a, f, t_from, t_to);
  job->client_id = entry.a;
  job->pair = entry.pair->pair;
  job->seq0 = entry.pair->seq0;
  job->seq1 = entry.pair->seq1;
  job->receive_utime = entry.pair->receive_utime;
  job->skeleton_a = entry.skeleton_a;
  job->motion_a = entry.motion_a;
  job->own_a = entry.own_a;
  job->own_e = e.own;  // Null for an object.
  if (job->cleared_by_box) {
    // Only the utimes are read (SharedMessageOf, the pair's batch key).
    job->pose0.utime = u0;
    job->pose1.utime = u1;
  } else {
    job->pose0 = entry.pair->pose0;
    job->pose1 = entry.pair->pose1;
  }
  job->entity = e.id;
  job->entity_is_object = e.is_object;
  job->skeleton_e = e.skeleton;
  job->motion_e = e.motion;
  job->mesh_e = e.mesh;
  job->avatar_samples.clear();
  job->object_samples.clear();
  for (size_t k = f; k <= l && !job->cleared_by_box; ++k) {
    if (e.is_object) {
      job->object_samples.push_back(e.object_samples[k]);
    } else {
      job->avatar_samples.push_back(e.avatar_samples[k]);
    }
  }
  job->t_from = t_from;
  job->t_to = t_to;
  // The window may reach before the oldest sample kept: then it is cut too.
  job->ended_by_timeout = cut || (e.evicted && e.utime(0) > u0);
  job->waited_us = MicrosSince(entry.pair->receive_time, cut ? now : e.last_sample_time);
  job->due_time = now;
  return true;
}

template <class Pred>
void SharedWorld::Settle(const std::string& id, Pred pred, bool cut, Time now,
                         std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end()) return;
  Entity& e = it->second;
  auto keep = e.pending.begin();
  for (auto x = e.pending.begin(); x != e.pending.end(); ++x) {
    if (pred(*x)) {
      SettleOne(e, *x, cut, now, due);
      continue;
    }
    if (keep != x) *keep = std::move(*x);
    ++keep;
  }
  e.pending.erase(keep, e.pending.end());
}

void SharedWorld::SettleOne(const Entity& e, const Entry& entry, bool cut, Time now,
                            std::vector<SharedJob>* due) {
  SharedJob job;
  if (!MakeJob(e, entry, cut, now, &job)) return;
  if (job.ended_by_timeout) ++entries_cut_;
  if (job.cleared_by_box) ++entries_cleared_;
  due->push_back(std::move(job));
}

void SharedWorld::AddPair(const std::string& id, const PosePair& pair, Time now,
                          std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end() || it->second.is_object) return;
  const Entity& a = it->second;
  // One copy of the pair and its box for all its entries: an entry then
  // allocates nothing of its own.
  auto shared = std::make_shared<SharedPair>();
  static_cast<PosePair&>(*shared) = pair;
  // A's box over the pair: the box of A's history interval holding the same
  // two poses when there is one (made as the second arrived), else made here.
  // (Searched from the newest sample: the pair is at or near the end.)
  size_t k = a.size();
  while (k > 0 && a.utime(k - 1) > pair.pose0.utime) --k;
  if (k > 0 && k < a.size() && SamePose(a.avatar_samples[k - 1], pair.pose0) &&
      SamePose(a.avatar_samples[k], pair.pose1)) {
    shared->box_a = a.boxes[k - 1];
  } else {
    shared->box_a = world::AvatarMotionBox(
        *a.skeleton, PairMotion(*a.skeleton, pair.pose0, pair.pose1, a.motion));
  }
  for (const std::string& other : order_) {
    if (other == id) continue;
    Entry entry;
    entry.a = id;
    entry.skeleton_a = a.skeleton;
    entry.motion_a = a.motion;
    entry.own_a = a.own;
    entry.pair = shared;
    entry.created = now;
    entry.number = next_entry_number_++;
    // Covered already (E is ahead): due now, never pending.
    Entity& e = entities_.at(other);
    if (Covered(e, entry)) {
      SettleOne(e, entry, /*cut=*/false, now, due);
    } else {
      e.pending.push_back(std::move(entry));
    }
  }
  // (Silence is cut by CutSilent, on the daemon's timer: not here, where a
  // scan of every entry per pair would cost O(entities x pending).)
  // Over the cap: the oldest entry of all (the least number among the
  // entities' oldest) is cut, as one list in creation order would cut.
  while (pending() > static_cast<size_t>(options_.max_pending)) {
    Entity* oldest = nullptr;
    for (auto& [other, e] : entities_) {
      if (!e.pending.empty() &&
          (oldest == nullptr || e.pending.front().number < oldest->pending.front().number)) {
        oldest = &e;
      }
    }
    SWEPTCCD_CHECK(oldest != nullptr);
    ++entries_overflowed_;
    SettleOne(*oldest, oldest->pending.front(), /*cut=*/true, now, due);
    oldest->pending.pop_front();
  }
}

void SharedWorld::CutSilent(Time now, std::vector<SharedJob>* due) {
  const auto timeout = std::chrono::microseconds(options_.silence_timeout_us);
  for (const std::string& id : order_) {
    const Entity& e = entities_.at(id);
    const bool silent = now - e.last_heard >= timeout;
    Settle(
        id, [&](const Entry& x) { return silent || now - x.created >= timeout; },
        /*cut=*/true, now, due);
  }
}

void SharedWorld::CutAll(Time now, std::vector<SharedJob>* due) {
  for (const std::string& id : order_) {
    Settle(
        id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
  }
}

}  // namespace sweptccd
