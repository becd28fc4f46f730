#include "service/collision_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <set>
#include <utility>

#include "core/errors.h"
#include "core/gpu/gl_context.h"
#include "core/percentile.h"
#include "core/query/result_json.h"
#include "msgs/text.h"
#include "service/contact_event.h"

namespace sweptccd {

namespace {

int64_t SystemUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double MicrosBetween(SteadyClock::time_point a, SteadyClock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

// What a client's configuration changes in the shared world's answers.
AvatarAnswerOptions AnswerOptionsOf(const ClientConfig& c) {
  return AvatarAnswerOptions{c.eps_s, c.delta_m, c.entity_rules};
}

}  // namespace

CollisionService::Client::Client(ClientConfig c, const Environment& env,
                                 const ServiceOptions& options)
    : config(std::move(c)),
      engine(std::make_unique<CcdEngine>(*config.skeleton, env, config.filter)),
      session(config.client_id, config.skeleton->num_links(), options.max_utime_jump_us),
      pose_bucket(options.max_pose_rate_hz, options.pose_burst) {
  if (options.device_descent == nullptr) return;
  try {
    descent_engine = options.device_descent->AddEngine(*engine);
    descent = options.device_descent;
  } catch (const gpu::GpuError& e) {
    // Its pairs are answered on the CPU alone (the same answers).
    spdlog::error("client '{}': the device descent refused its engine: {}", config.client_id,
                  e.what());
  }
}

CollisionService::Client::~Client() {
  if (descent != nullptr) descent->RemoveEngine(descent_engine);
}

namespace {

void CheckRateOptions(const ServiceOptions& o) {
  if (!(o.max_pose_rate_hz > 0 && o.max_pose_rate_hz <= 1e6) || o.pose_burst < 1) {
    throw InputError("collision service: max_pose_rate_hz " + std::to_string(o.max_pose_rate_hz) +
                     " / pose_burst " + std::to_string(o.pose_burst) +
                     "; use a rate in (0, 1e6] Hz and a burst of 1 or more");
  }
  if (!(o.max_object_pose_rate_hz > 0 && o.max_object_pose_rate_hz <= 1e6) ||
      o.object_pose_burst < 1) {
    throw InputError("collision service: max_object_pose_rate_hz " +
                     std::to_string(o.max_object_pose_rate_hz) + " / object_pose_burst " +
                     std::to_string(o.object_pose_burst) +
                     "; use a rate in (0, 1e6] Hz and a burst of 1 or more");
  }
  if (!(o.rejection_rate_hz > 0 && o.rejection_rate_hz <= 1e6) || o.rejection_burst < 1 ||
      o.rejection_max_keys < 1) {
    throw InputError(
        "collision service: rejection_rate_hz, rejection_burst and "
        "rejection_max_keys must be > 0");
  }
}

}  // namespace

CollisionService::CollisionService(std::shared_ptr<const Environment> environment,
                                   std::vector<ClientConfig> clients, ServiceOptions options,
                                   Publisher* publisher)
    : environment_(std::move(environment)),
      options_(std::move(options)),
      publisher_(publisher),
      rejection_throttle_(options_.rejection_rate_hz, options_.rejection_burst,
                          options_.rejection_max_keys) {
  if (!environment_) throw InputError("collision service: no environment");
  if (!publisher_) throw InputError("collision service: no publisher");
  if (clients.empty() && options_.max_live_clients < 1) {
    throw InputError(
        "collision service: no clients registered and live joins are off; add at "
        "least one, or allow max_live_clients");
  }
  if (options_.max_live_clients < 0 || options_.silence_timeout_ms < 1) {
    throw InputError(
        "collision service: max_live_clients must be >= 0 and silence_timeout_ms "
        ">= 1");
  }
  if (options_.num_workers < 1) {
    throw InputError("collision service: num_workers is " + std::to_string(options_.num_workers) +
                     "; use 1 or more");
  }
  if (options_.descent_max_batch < 1 || options_.descent_max_batch > 4096 ||
      options_.descent_gather_us < 0 || options_.descent_gather_us > 100000) {
    throw InputError("collision service: descent_max_batch " +
                     std::to_string(options_.descent_max_batch) + " / descent_gather_us " +
                     std::to_string(options_.descent_gather_us) +
                     "; use 1 to 4096 pairs and 0 to 100000 us");
  }
  if (options_.latency_window < 1) {
    throw InputError("collision service: latency_window is " +
                     std::to_string(options_.latency_window) + "; use 1 or more");
  }
  const std::string problem = ValidateQueryOptions(options_.query);
  if (!problem.empty()) throw InputError("collision service: " + problem);
  if (!options_.clock_utime) options_.clock_utime = SystemUtime;
  CheckRateOptions(options_);
  if (options_.max_utime_jump_us < 1) {
    throw InputError("collision service: max_utime_jump_us is " +
                     std::to_string(options_.max_utime_jump_us) + "; use 1 or more");
  }
  for (ClientConfig& c : clients) {
    if (!IsValidClientId(c.client_id)) {
      throw InputError("collision service: client id '" + EscapeForDisplay(c.client_id) +
                       "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
    }
    if (!c.skeleton || c.skeleton->num_links() < 1) {
      throw InputError("collision service: client '" + c.client_id + "' has no skeleton");
    }
    if (configured_ids_.count(c.client_id)) {
      throw InputError("collision service: client '" + c.client_id +
                       "' is registered twice; give every client its own id");
    }
    configured_ids_.insert(c.client_id);
    clients_.push_back(std::make_shared<Client>(std::move(c), *environment_, options_));
    client_index_[clients_.back()->config.client_id] = clients_.back();
    if (options_.prepare_engine) options_.prepare_engine(clients_.back()->engine.get());
  }
  if (!options_.shared_world && !options_.objects.empty()) {
    throw InputError(
        "collision service: tracked objects need the shared world; set "
        "shared_world: true, or remove the objects");
  }
  if (options_.shared_world) {
    SharedWorldOptions so;
    so.silence_timeout_us = options_.silence_timeout_ms * 1000;
    so.max_history = options_.shared_max_history;
    so.max_pending = options_.shared_max_pending;
    shared_ = std::make_unique<SharedWorld>(so);
    entity_options_.eps_s = options_.query.eps_s;
    entity_options_.delta_m = options_.query.delta_m;
    entity_options_.max_intervals = options_.query.max_intervals;
    entity_options_.per_link = options_.query.per_link;
    const SteadyClock::time_point now = SteadyClock::now();
    for (const auto& c : clients_) {
      shared_->AddAvatar(c->config.client_id, c->config.skeleton, c->config.motion, now,
                         AnswerOptionsOf(c->config));
    }
    for (const TrackedObjectConfig& o : options_.objects) {
      if (!IsValidClientId(o.object_id)) {
        throw InputError("collision service: object id '" + EscapeForDisplay(o.object_id) +
                         "' breaks the id rule; use 1-64 characters from A-Z a-z 0-9 _ . -");
      }
      if (configured_ids_.count(o.object_id) || shared_->Has(o.object_id)) {
        throw InputError("collision service: id '" + o.object_id +
                         "' names two entities; give every client and object its own id");
      }
      if (!o.mesh || o.mesh->num_objects() != 1) {
        throw InputError("collision service: object '" + o.object_id + "' needs exactly one mesh");
      }
      shared_->AddObject(o.object_id, o.mesh, now);
      object_inputs_.emplace(o.object_id, ObjectInput{TokenBucket(options_.max_object_pose_rate_hz,
                                                                  options_.object_pose_burst),
                                                      0});
    }
  }
  instance_ = NowUtime();
  workers_.reserve(options_.num_workers);
  for (int i = 0; i < options_.num_workers; ++i) {
    workers_.emplace_back([this] { WorkerLoop(); });
  }
}

CollisionService::~CollisionService() { Stop(); }

int64_t CollisionService::NowUtime() const { return options_.clock_utime(); }

void CollisionService::OnPose(const tracker_pose_t& pose) {
  const int64_t receive_utime = NowUtime();
  const SteadyClock::time_point receive_time = SteadyClock::now();
  std::optional<Rejection> rejection;
  bool attributed = false;
  bool queued = false;  // A pair became ready: a worker is woken after the lock.
  bool taken = false;   // Accepted (forwarded to viewers).
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) {
      ++ignored_after_stop_;
      return;
    }
    const size_t ready_before = ready_.size();
    auto it = client_index_.end();
    if (!IsValidClientId(pose.client_id)) {
      ++rejected_unattributed_;
      rejection =
          Rejection{rejection_code::kBadClientId,
                    "client_id '" + EscapeForDisplay(pose.client_id) +
                        "' breaks the id rule; send 1-64 characters from A-Z a-z 0-9 _ . -"};
    } else if ((it = client_index_.find(pose.client_id)) == client_index_.end()) {
      ++rejected_unattributed_;
      rejection = Rejection{rejection_code::kUnknownClient,
                            "client_id '" + pose.client_id +
                                "' is not registered; register it in the service configuration "
                                "or join it (SWEPTCCD_JOIN)"};
    } else {
      attributed = true;
      const int64_t shed_before = it->second->rate_limited;
      rejection = AdmitLocked(it->second, pose, receive_utime, receive_time);
      taken = !rejection && it->second->rate_limited == shed_before;
      if (it->second->live || (it->second->held && pose.session == it->second->assigned_session)) {
        it->second->last_heard = receive_time;
      }
    }
    queued = ready_.size() > ready_before;
  }
  // Notified after the lock is released: the woken worker takes the mutex at
  // once instead of waking into a lock this thread still holds.
  if (queued) work_cv_.notify_one();
  if (taken) SafePublish([&] { publisher_->ForwardPose(pose); }, "forwarded pose");
  if (rejection) {
    // An id that breaks the rule is not echoed in rejection_t.client_id.
    Reject(IsValidClientId(pose.client_id) ? pose.client_id : "", pose.seq, *rejection, attributed);
  }
}

std::optional<Rejection> CollisionService::AdmitLocked(const std::shared_ptr<Client>& index,
                                                       const tracker_pose_t& pose,
                                                       int64_t receive_utime,
                                                       SteadyClock::time_point receive_time) {
  Client& client = *index;
  if (!client.pose_bucket.TryTake(receive_utime)) {
    ++client.rate_limited;
    return Rejection{rejection_code::kRateLimited,
                     "client '" + pose.client_id + "' sends faster than max_pose_rate_hz " +
                         std::to_string(options_.max_pose_rate_hz) +
                         "; pose shed unread; lower the tracker's rate"};
  }
  if (client.live && pose.session != client.assigned_session) {
    return Rejection{rejection_code::kStaleSession,
                     "session " + std::to_string(pose.session) + " of live client '" +
                         pose.client_id + "' is not the session " +
                         std::to_string(client.assigned_session) +
                         " its join was given; send that one, or join again"};
  }
  const bool was_ready = client.session.ready();
  std::optional<Rejection> rejection = client.session.OnPose(pose, receive_utime, receive_time);
  if (!rejection && shared_) {
    std::vector<SharedJob> due;
    shared_->OnAvatarSample(client.config.client_id, client.session.session(),
                            *client.session.last_pose(), receive_time, &due);
    QueueSharedLocked(&due);
  }
  if (!rejection && !was_ready && client.session.ready()) {
    ready_.push_back(index);  // The caller wakes a worker once the lock is released.
  }
  return rejection;
}

void CollisionService::QueueSharedLocked(std::vector<SharedJob>* due) {
  if (due->empty()) return;
  const size_t max_entries = static_cast<size_t>(shared_contact_t::MAX_ENTRIES);
  for (SharedJob& job : *due) {
    PairKey key{job.client_id, job.pair, job.seq0, job.seq1, job.pose1.utime};
    auto open = shared_open_.find(key);
    if (open == shared_open_.end()) {
      shared_ready_.push_back(SharedBatch{key, {}});
      open = shared_open_.emplace(std::move(key), std::prev(shared_ready_.end())).first;
    }
    std::vector<SharedJob>& jobs = open->second->jobs;
    jobs.push_back(std::move(job));
    ++shared_ready_entries_;
    if (jobs.size() >= max_entries) shared_open_.erase(open);  // Full: the next opens another.
  }
  due->clear();
  // Bounded: when the workers cannot keep up, the oldest due entries are
  // dropped unanswered and counted (shared_dropped, the log), never queued
  // without bound.
  int64_t dropped = 0;
  while (static_cast<int>(shared_ready_entries_) > options_.shared_max_pending) {
    SharedBatch& oldest = shared_ready_.front();
    oldest.jobs.erase(oldest.jobs.begin());
    --shared_ready_entries_;
    ++dropped;
    if (oldest.jobs.empty()) TakeSharedBatchLocked();
  }
  if (dropped > 0) {
    if (shared_dropped_ == 0 || (shared_dropped_ + dropped) / 1000 != shared_dropped_ / 1000) {
      spdlog::warn("shared world: {} due entries dropped unanswered so far (workers behind)",
                   shared_dropped_ + dropped);
    }
    shared_dropped_ += dropped;
  }
  work_cv_.notify_all();
}

CollisionService::SharedBatch CollisionService::TakeSharedBatchLocked() {
  SWEPTCCD_CHECK(!shared_ready_.empty());
  const auto open = shared_open_.find(shared_ready_.front().key);
  if (open != shared_open_.end() && open->second == shared_ready_.begin()) {
    shared_open_.erase(open);
  }
  SharedBatch batch = std::move(shared_ready_.front());
  shared_ready_.pop_front();
  shared_ready_entries_ -= batch.jobs.size();
  return batch;
}

size_t CollisionService::AnswerSharedBatch(const SharedBatch& batch) {
  // Environment parts go first: once a batch has taken kSharedSlice and one
  // waits, what is answered goes out now and the rest goes back to the
  // queue. (Not after every entry: under load an environment part is nearly
  // always waiting, and batches would shrink to one entry a message again.)
  constexpr auto kSharedSlice = std::chrono::microseconds(500);
  const SteadyClock::time_point start = SteadyClock::now();
  shared_contact_t msg = SharedMessageOf(batch.jobs.front());
  msg.entries.reserve(batch.jobs.size());
  for (const SharedJob& job : batch.jobs) {
    if (!msg.entries.empty() && SteadyClock::now() - start >= kSharedSlice) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!ready_.empty()) break;
    }
    msg.entries.push_back(AnswerSharedJob(job, entity_options_));
    const shared_entry_t& entry = msg.entries.back();
    if (entry.result == shared_entry_t::RESULT_INVALID) {
      spdlog::error("client '{}' pair {} against '{}': {}", job.client_id, job.pair, job.entity,
                    EscapeForDisplay(entry.error, 1024));
    }
  }
  msg.num_entries = static_cast<int32_t>(msg.entries.size());
  msg.utime = NowUtime();
  SafePublish([&] { publisher_->PublishSharedContact(msg); }, "shared contact");
  return msg.entries.size();
}

void CollisionService::OnObjectPose(const object_pose_t& pose) {
  const SteadyClock::time_point receive_time = SteadyClock::now();
  std::optional<Rejection> rejection;
  bool attributed = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) {
      ++ignored_after_stop_;
      return;
    }
    ++object_poses_received_;
    const auto input = object_inputs_.find(pose.object_id);
    if (!shared_) {
      rejection = Rejection{rejection_code::kUnknownObject,
                            "this daemon runs without the shared world (shared_world: false); "
                            "object poses are not taken"};
    } else if (input != object_inputs_.end() && !input->second.bucket.TryTake(NowUtime())) {
      // Shed before anything is read of it (as a client's poses, AdmitLocked).
      ++input->second.rate_limited;
      ++object_poses_rate_limited_;
      rejection = Rejection{rejection_code::kRateLimited,
                            "object '" + pose.object_id +
                                "' sends faster than "
                                "max_object_pose_rate_hz " +
                                std::to_string(options_.max_object_pose_rate_hz) +
                                "; pose shed unread; lower the tracker's rate"};
    } else {
      std::vector<SharedJob> due;
      rejection = shared_->OnObjectPose(pose, options_.max_utime_jump_us, receive_time, &due);
      QueueSharedLocked(&due);
    }
    attributed = rejection && rejection->reason != rejection_code::kUnknownObject;
    if (rejection && !attributed) ++rejected_unattributed_;
    if (rejection && rejection->reason != rejection_code::kRateLimited) ++object_poses_rejected_;
  }
  if (rejection) {
    Reject(IsValidClientId(pose.object_id) ? pose.object_id : "", pose.seq, *rejection, attributed);
  } else {
    SafePublish([&] { publisher_->ForwardObjectPose(pose); }, "forwarded object pose");
  }
}

void CollisionService::OnRefused(const std::string& client_id, const Rejection& rejection) {
  SWEPTCCD_CHECK(client_id.empty() || IsValidClientId(client_id));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) {
      ++ignored_after_stop_;
      return;
    }
    ++rejected_unattributed_;
  }
  Reject(client_id, -1, rejection, /*attributed=*/false);
}

void CollisionService::OnUndecodable(const std::string& channel, const std::string& problem,
                                     const char* type) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) {
      ++ignored_after_stop_;
      return;
    }
    ++rejected_unattributed_;
  }
  Reject(
      "", -1,
      Rejection{rejection_code::kDecodeError,
                "message on channel " + channel + " could not be decoded as " + std::string(type) +
                    " (" + problem + "); publish " + type + " built from this service's msgs/"},
      /*attributed=*/false);
}

void CollisionService::Reject(const std::string& client_id, int64_t seq, const Rejection& rejection,
                              bool attributed) {
  const int64_t now_us = NowUtime();
  int64_t held_back = 0;
  {
    // Rejections no registered client can be blamed for (unknown or bad ids,
    // bad signatures, undecodable bytes) share the key "": forging a client's
    // id cannot spend that client's budget.
    std::lock_guard<std::mutex> lock(mutex_);
    held_back = rejection_throttle_.Admit(attributed ? client_id : "", now_us);
  }
  LogRejection(client_id, seq, rejection, now_us);
  if (held_back < 0) return;
  rejection_t msg;
  msg.utime = now_us;
  msg.client_id = client_id;
  msg.seq = seq;
  msg.reason = rejection.reason;
  msg.message = rejection.message;
  msg.suppressed = held_back;
  SafePublish([&] { publisher_->PublishRejection(msg); }, "rejection");
}

// Logged at a limited rate: at most 10 lines a second, then a count.
void CollisionService::LogRejection(const std::string& client_id, int64_t seq,
                                    const Rejection& rejection, int64_t now_us) {
  bool log = false;
  int64_t suppressed = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (now_us - rejection_log_window_start_us_ >= 1'000'000) {
      rejection_log_window_start_us_ = now_us;
      rejection_logs_in_window_ = 0;
      suppressed = rejection_logs_suppressed_;
      rejection_logs_suppressed_ = 0;
    }
    if (rejection_logs_in_window_ < 10) {
      ++rejection_logs_in_window_;
      log = true;
    } else {
      ++rejection_logs_suppressed_;
    }
  }
  if (suppressed > 0) spdlog::warn("{} rejection log lines suppressed", suppressed);
  if (log) {
    spdlog::warn("rejected pose of client '{}' seq {}: {}: {}", EscapeForDisplay(client_id), seq,
                 rejection.reason, EscapeForDisplay(rejection.message, 1024));
  }
}

void CollisionService::SafePublish(const std::function<void()>& publish, const char* what) {
  try {
    publish();
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++publish_errors_;
    spdlog::error("publishing a {} failed: {}", what, e.what());
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++publish_errors_;
    spdlog::error("publishing a {} failed with an unknown exception", what);
  }
}

contact_event_t CollisionService::Answer(const Client& client, const PosePair& pair,
                                         double queue_us, const PairClears* clears) const {
  contact_event_t ev;
  ev.client_id = client.config.client_id;
  ev.seq0 = pair.seq0;
  ev.seq1 = pair.seq1;
  ev.pair = pair.pair;
  ev.utime0 = pair.pose0.utime;
  ev.utime1 = pair.pose1.utime;
  ev.receive_utime = pair.receive_utime;
  ev.queue_us = queue_us;
  ev.skipped_pairs_total = pair.skipped_pairs_total;

  QueryOptions options = options_.query;
  options.motion = client.config.motion;
  if (client.config.eps_s > 0) options.eps_s = client.config.eps_s;
  if (client.config.delta_m > 0) options.delta_m = client.config.delta_m;
  const SteadyClock::time_point start = SteadyClock::now();
  try {
    const QueryResult r = client.engine->Query(pair.pose0, pair.pose1, options, clears);
    FillContactEvent(MakeResultRecord(ev.pair, ev.utime0, ev.utime1, r, options.per_link), &ev);
  } catch (const std::exception& e) {
    // Not expected (the poses were validated); answered, never lost.
    MarkContactEventInvalid(std::string("query failed: ") + e.what(), &ev);
  } catch (...) {
    MarkContactEventInvalid("query failed with an unknown exception", &ev);
  }
  if (ev.result == contact_event_t::RESULT_INVALID) {
    spdlog::error("client '{}' pair {}: {}", ev.client_id, ev.pair,
                  EscapeForDisplay(ev.error, 1024));
  }
  ev.compute_us = MicrosBetween(start, SteadyClock::now());
  return ev;
}

void CollisionService::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    work_cv_.wait(lock, [this] {
      return !ready_.empty() || !shared_ready_.empty() || (stopping_ && in_flight_ == 0);
    });
    if (ready_.empty() && shared_ready_.empty()) break;  // Stopping, nothing left anywhere.
    if (ready_.empty()) {
      // A batch of shared entries (one pair's): environment parts go first
      // (their latency never waits for the shared world).
      SharedBatch batch = TakeSharedBatchLocked();
      ++in_flight_;
      lock.unlock();
      const size_t answered = AnswerSharedBatch(batch);
      int64_t by_timeout = 0;
      for (size_t i = 0; i < answered; ++i) by_timeout += batch.jobs[i].ended_by_timeout;
      lock.lock();
      if (answered < batch.jobs.size()) {
        // Interrupted for an environment part: the rest is next, as a batch
        // of its own (entries due later for this pair start another).
        batch.jobs.erase(batch.jobs.begin(), batch.jobs.begin() + static_cast<ptrdiff_t>(answered));
        shared_ready_entries_ += batch.jobs.size();
        shared_ready_.push_front(std::move(batch));
        work_cv_.notify_one();
      }
      shared_published_ += static_cast<int64_t>(answered);
      shared_by_timeout_ += by_timeout;
      ++shared_messages_;
      --in_flight_;
      if (IdleLocked()) {
        idle_cv_.notify_all();
        if (stopping_) work_cv_.notify_all();
      }
      continue;
    }
    if (options_.device_descent != nullptr) {
      AnswerDescentBatch(&lock);
      continue;
    }
    const std::shared_ptr<Client> index = ready_.front();
    ready_.pop_front();
    Client& client = *index;
    if (client.removed) {  // Left or expired: its pending pair goes with it.
      if (IdleLocked()) {
        idle_cv_.notify_all();
        if (stopping_) work_cv_.notify_all();
      }
      continue;
    }
    PosePair pair = client.session.TakePair();
    ++in_flight_;
    lock.unlock();

    const double queue_us = MicrosBetween(pair.receive_time, SteadyClock::now());
    contact_event_t event = Answer(client, pair, queue_us);
    event.utime = NowUtime();
    SafePublish([&] { publisher_->PublishContact(event); }, "contact event");
    const double latency_us = MicrosBetween(pair.receive_time, SteadyClock::now());

    lock.lock();
    FinishPairLocked(index, pair, latency_us);
  }
}

void CollisionService::FinishPairLocked(const std::shared_ptr<Client>& index, const PosePair& pair,
                                        double latency_us) {
  Client& client = *index;
  client.latencies_us.push_back(latency_us);
  latency_histogram_.ObserveMicros(latency_us);
  while (static_cast<int>(client.latencies_us.size()) > options_.latency_window) {
    client.latencies_us.pop_front();
  }
  client.session.FinishPair();
  if (shared_ && !client.removed) {
    // The pair's shared part, after its environment part was published:
    // entries the other entities cover already are due at once.
    std::vector<SharedJob> due;
    const SteadyClock::time_point now = SteadyClock::now();
    shared_->AddPair(client.config.client_id, pair, now, &due);
    if (stopping_) shared_->CutAll(now, &due);
    QueueSharedLocked(&due);
  }
  --in_flight_;
  if (client.session.ready() && !client.removed) {
    ready_.push_back(index);
    work_cv_.notify_one();
  }
  if (IdleLocked()) {
    idle_cv_.notify_all();
    if (stopping_) work_cv_.notify_all();  // Let the other workers leave.
  }
}

void CollisionService::AnswerDescentBatch(std::unique_lock<std::mutex>* lock) {
  std::vector<std::shared_ptr<Client>> clients;
  std::vector<PosePair> pairs;
  const size_t max_batch = static_cast<size_t>(options_.descent_max_batch);
  // Takes the ready clients' pairs (a client is in ready_ once at most and
  // never while its pair is in flight: one pair per client in a batch).
  auto take = [&] {
    while (!ready_.empty() && clients.size() < max_batch) {
      std::shared_ptr<Client> index = ready_.front();
      ready_.pop_front();
      if (index->removed) continue;  // Left or expired: its pending pair goes with it.
      pairs.push_back(index->session.TakePair());
      clients.push_back(std::move(index));
      ++in_flight_;
    }
  };
  take();
  if (!clients.empty() && options_.descent_gather_us > 0 && clients_.size() > 1) {
    // The gather window, counted from the oldest pair's receipt.
    SteadyClock::time_point oldest = pairs.front().receive_time;
    for (const PosePair& p : pairs) oldest = std::min(oldest, p.receive_time);
    const SteadyClock::time_point deadline =
        oldest + std::chrono::microseconds(options_.descent_gather_us);
    while (clients.size() < max_batch && !stopping_ && clients.size() < clients_.size() &&
           work_cv_.wait_until(*lock, deadline, [this] { return !ready_.empty() || stopping_; })) {
      take();
    }
  }
  if (clients.empty()) {
    if (IdleLocked()) {
      idle_cv_.notify_all();
      if (stopping_) work_cv_.notify_all();
    }
    return;
  }
  lock->unlock();

  // The batch's environment parts on the device (engines it refused: none).
  std::vector<gpu::DeviceDescent::Pair> descent_pairs;
  std::vector<size_t> descent_slot;
  for (size_t i = 0; i < clients.size(); ++i) {
    if (clients[i]->descent_engine < 0) continue;
    descent_pairs.push_back(
        {clients[i]->descent_engine, &pairs[i].pose0, &pairs[i].pose1, clients[i]->config.motion});
    descent_slot.push_back(i);
  }
  std::vector<PairClears> clears;
  std::vector<const PairClears*> clears_of(clients.size(), nullptr);
  if (!descent_pairs.empty()) {
    try {
      // A GPU failure clears nothing (logged once): the CPU answers alone.
      (void)options_.device_descent->Run(descent_pairs, options_.query, &clears);
      for (size_t j = 0; j < descent_slot.size(); ++j) clears_of[descent_slot[j]] = &clears[j];
    } catch (const std::exception& e) {
      // Not expected; the batch is answered on the CPU alone, never lost.
      spdlog::error("device descent batch of {} pairs failed: {}", descent_pairs.size(),
                    EscapeForDisplay(e.what(), 1024));
    }
  }
  // Answered and published in the order taken, each client's bookkeeping
  // right after its own publication.
  for (size_t i = 0; i < clients.size(); ++i) {
    const PosePair& pair = pairs[i];
    const double queue_us = MicrosBetween(pair.receive_time, SteadyClock::now());
    contact_event_t event = Answer(*clients[i], pair, queue_us, clears_of[i]);
    event.utime = NowUtime();
    SafePublish([&] { publisher_->PublishContact(event); }, "contact event");
    const double latency_us = MicrosBetween(pair.receive_time, SteadyClock::now());
    lock->lock();
    FinishPairLocked(clients[i], pair, latency_us);
    lock->unlock();
  }
  lock->lock();
}

void CollisionService::WaitUntilIdle() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_cv_.wait(lock, [this] { return IdleLocked(); });
}

void CollisionService::Stop() {
  std::lock_guard<std::mutex> stop_lock(stop_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    if (shared_) {
      // Nothing more will arrive: what still waits ends now (ended_by_timeout).
      std::vector<SharedJob> due;
      shared_->CutAll(SteadyClock::now(), &due);
      QueueSharedLocked(&due);
    }
  }
  work_cv_.notify_all();
  for (std::thread& t : workers_) {
    if (t.joinable()) t.join();
  }
  workers_.clear();
  idle_cv_.notify_all();
}

LatencyHistogram CollisionService::latency_histogram() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latency_histogram_;
}

status_t CollisionService::Status() const {
  status_t s;
  s.utime = NowUtime();
  s.backend = options_.backend_state ? options_.backend_state() : options_.backend;
  s.renderer = options_.renderer;
  s.security = options_.security;
  std::lock_guard<std::mutex> lock(mutex_);
  s.num_clients = static_cast<int32_t>(clients_.size());
  s.instance = instance_;
  s.live_joined = live_joined_;
  s.live_left = live_left_;
  s.live_expired = live_expired_;
  int32_t pending = 0;
  int64_t dropped = 0;
  for (const auto& c : clients_) {
    const ClientSession& cs = c->session;
    s.client_id.push_back(cs.client_id());
    s.poses_received.push_back(cs.poses_received() + c->rate_limited);
    s.pairs_answered.push_back(cs.pairs_finished());
    s.pairs_skipped.push_back(cs.pairs_skipped());
    s.rejected.push_back(cs.rejected());
    s.seq_gaps.push_back(cs.seq_gaps());
    s.rate_limited.push_back(c->rate_limited);
    std::vector<double> lat(c->latencies_us.begin(), c->latencies_us.end());
    s.latency_median_us.push_back(Percentile(lat, 0.5));
    s.latency_p99_us.push_back(Percentile(std::move(lat), 0.99));
    if (cs.has_pending()) ++pending;
    dropped += cs.pairs_skipped();
  }
  s.queue_depth = pending;
  s.dropped_total = dropped;
  s.rejected_unattributed = rejected_unattributed_;
  s.rejections_suppressed = rejection_throttle_.suppressed_total();
  s.shared_messages = shared_messages_;
  s.shared_entries = shared_published_;
  s.shared_by_timeout = shared_by_timeout_;
  s.shared_dropped = shared_dropped_;
  s.shared_overflowed = shared_ ? shared_->entries_overflowed() : 0;
  s.shared_cleared = shared_ ? shared_->entries_cleared() : 0;
  s.shared_pending = shared_ ? static_cast<int32_t>(shared_->pending()) : 0;
  s.shared_ready = static_cast<int32_t>(shared_ready_entries_);
  s.object_poses_received = object_poses_received_;
  s.object_poses_rejected = object_poses_rejected_;
  s.object_poses_rate_limited = object_poses_rate_limited_;
  return s;
}

void CollisionService::PublishStatus() {
  const status_t s = Status();
  SafePublish([&] { publisher_->PublishStatus(s); }, "status");
}

bool CollisionService::IsConfigured(const std::string& client_id) const {
  return configured_ids_.count(client_id) > 0;  // Immutable: no lock.
}

int CollisionService::live_clients() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(clients_.size() - configured_ids_.size());
}

bool CollisionService::LiveKey(const std::string& client_id, std::optional<MacKey>* key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = client_index_.find(client_id);
  if (it == client_index_.end() || !it->second->live) return false;
  *key = it->second->key;
  return true;
}

std::vector<RoomClient> CollisionService::RoomClients() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<RoomClient> out;
  out.reserve(clients_.size());
  for (const auto& c : clients_) {
    out.push_back({c->config.client_id, c->live, c->config.skeleton, c->config.motion});
  }
  return out;
}

int64_t CollisionService::room_version() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return room_version_;
}

void CollisionService::RemoveLocked(const std::shared_ptr<Client>& client) {
  ++room_version_;
  client->removed = true;
  if (shared_) {
    std::vector<SharedJob> due;
    shared_->RemoveAvatar(client->config.client_id, SteadyClock::now(), &due);
    QueueSharedLocked(&due);
  }
  client_index_.erase(client->config.client_id);
  clients_.erase(std::remove(clients_.begin(), clients_.end(), client), clients_.end());
}

LiveJoinOutcome CollisionService::JoinLive(LiveJoinRequest request,
                                           std::optional<MacKey> fresh_key) {
  const std::string id = request.config.client_id;
  LiveJoinOutcome out;
  // Cheap checks first, so a refused join never builds an engine.
  auto check = [&]() -> bool {
    if (stopping_) {
      out = {
          join_reply_t::REASON_BUSY, "the daemon is stopping; join again when it is back", 0, {}};
      return false;
    }
    if (configured_ids_.count(id)) {
      out = {join_reply_t::REASON_ID_IN_USE,
             "client id '" + id +
                 "' is a configured client of this daemon: it sends its poses signed with its "
                 "key without a join (or joins through the WebSocket door); pick another id",
             0,
             {}};
      return false;
    }
    if (shared_ && shared_->Has(id) && !client_index_.count(id)) {
      out = {join_reply_t::REASON_ID_IN_USE,
             "id '" + id + "' is a tracked object of this daemon; pick another id",
             0,
             {}};
      return false;
    }
    const auto it = client_index_.find(id);
    if (it != client_index_.end()) {
      const Client& c = *it->second;
      if (c.nonce == request.nonce && c.public_key == request.public_key) {
        out = {join_reply_t::REASON_ACCEPTED, "", c.assigned_session, c.key};  // A lost reply.
      } else {
        out = {join_reply_t::REASON_ID_IN_USE,
               "client id '" + id + "' is in use by another live session (session " +
                   std::to_string(c.assigned_session) + "); pick another id, or wait " +
                   std::to_string(options_.silence_timeout_ms) + " ms after its last pose",
               0,
               {}};
      }
      return false;
    }
    const int live = static_cast<int>(clients_.size() - configured_ids_.size());
    if (live >= options_.max_live_clients) {
      out = {options_.max_live_clients == 0 ? join_reply_t::REASON_JOINS_DISABLED
                                            : join_reply_t::REASON_TOO_MANY_CLIENTS,
             options_.max_live_clients == 0
                 ? std::string("this daemon takes no live clients (max_live_clients: 0); "
                               "configure the client instead")
                 : std::to_string(live) +
                       " live clients already, the limit max_live_clients; "
                       "try later or raise it",
             0,
             {}};
      return false;
    }
    return true;
  };
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!stopping_ && configured_ids_.count(id) && request.proven_with_client_key) {
      return ClaimConfiguredLocked(request);
    }
    if (!check()) return out;
  }
  if (!request.config.skeleton || request.config.skeleton->num_links() < 1) {
    return {join_reply_t::REASON_BAD_SKELETON, "the skeleton has no links", 0, {}};
  }
  // The engine is built without the lock: workers keep answering meanwhile.
  auto client = std::make_shared<Client>(std::move(request.config), *environment_, options_);
  if (options_.prepare_engine) options_.prepare_engine(client->engine.get());
  client->live = true;
  client->nonce = request.nonce;
  client->public_key = request.public_key;
  client->key = std::move(fresh_key);
  client->last_heard = SteadyClock::now();
  std::lock_guard<std::mutex> lock(mutex_);
  if (!check()) return out;  // Only the join thread adds, but stay exact.
  client->assigned_session = std::max(last_session_ + 1, NowUtime());
  last_session_ = client->assigned_session;
  clients_.push_back(client);
  client_index_[id] = client;
  ++room_version_;
  if (shared_) {
    shared_->AddAvatar(id, client->config.skeleton, client->config.motion, SteadyClock::now(),
                       AnswerOptionsOf(client->config));
  }
  ++live_joined_;
  return {join_reply_t::REASON_ACCEPTED, "", client->assigned_session, client->key};
}

LiveJoinOutcome CollisionService::ClaimConfiguredLocked(const LiveJoinRequest& request) {
  const std::string& id = request.config.client_id;
  Client& c = *client_index_.at(id);
  const Skeleton& want = *c.config.skeleton;
  const Skeleton* got = request.config.skeleton.get();
  bool same = got != nullptr && got->num_links() == want.num_links();
  for (int i = 0; same && i < want.num_links(); ++i) {
    const Link &a = want.link(i), &b = got->link(i);
    same = a.name == b.name && a.parent == b.parent && a.a_L == b.a_L && a.b_L == b.b_L &&
           a.radius == b.radius;
  }
  if (!same) {
    return {join_reply_t::REASON_BAD_SKELETON,
            "'" + id + "' is a configured client: join with its configured skeleton (" +
                std::to_string(want.num_links()) +
                " links, the same names, parents, segments and radii)",
            0,
            {}};
  }
  if (request.config.motion != c.config.motion || request.config.eps_s != c.config.eps_s ||
      request.config.delta_m != c.config.delta_m) {
    return {join_reply_t::REASON_BAD_OPTIONS,
            "'" + id +
                "' is a configured client: its motion and tolerances are the configuration's; "
                "join with motion " +
                std::to_string(c.config.motion == MotionModel::kIndependent ? 1 : 0) +
                " and eps_s, delta_m 0",
            0,
            {}};
  }
  if (request.ignore_rules > 0 || !request.config.entity_rules.empty()) {
    return {join_reply_t::REASON_BAD_FILTER,
            "'" + id +
                "' is a configured client: its filters are the configuration's; join without "
                "ignore and ignore_entity rules",
            0,
            {}};
  }
  const auto now = SteadyClock::now();
  const auto timeout = std::chrono::milliseconds(options_.silence_timeout_ms);
  if (c.held && c.nonce != request.nonce && now - c.last_heard < timeout) {
    return {join_reply_t::REASON_ID_IN_USE,
            "configured client '" + id + "' is held by another connection (session " +
                std::to_string(c.assigned_session) + "); pick another id, or wait " +
                std::to_string(options_.silence_timeout_ms) + " ms after its last pose",
            0,
            {}};
  }
  // A new stream: greater than every session handed out and than the
  // client's own (an LCM tracker's start time), so older streams are stale.
  c.held = true;
  c.nonce = request.nonce;
  c.assigned_session = std::max({last_session_ + 1, NowUtime(), c.session.session() + 1});
  last_session_ = c.assigned_session;
  c.last_heard = now;
  return {join_reply_t::REASON_ACCEPTED, "", c.assigned_session, std::nullopt};
}

bool CollisionService::LeaveLive(const std::string& client_id, int64_t session) {
  // Declared before the lock: the client (its engine and buffers) is freed
  // after the lock is released, so no worker waits on a leave's frees.
  std::shared_ptr<Client> leaving;
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = client_index_.find(client_id);
  if (it != client_index_.end() && it->second->held && !it->second->live &&
      it->second->assigned_session == session) {
    it->second->held = false;  // A configured client stays; only its hold ends.
    return true;
  }
  if (it == client_index_.end() || !it->second->live || it->second->assigned_session != session) {
    return false;
  }
  leaving = it->second;
  RemoveLocked(leaving);
  ++live_left_;
  return true;
}

std::vector<std::string> CollisionService::ExpireSilent(SteadyClock::time_point now) {
  const auto timeout = std::chrono::milliseconds(options_.silence_timeout_ms);
  std::vector<std::string> expired;
  std::vector<std::shared_ptr<Client>> silent;  // Freed after the lock, as in LeaveLive.
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& c : clients_) {
    if (c->live && now - c->last_heard >= timeout) silent.push_back(c);
  }
  for (const auto& c : silent) {
    expired.push_back(c->config.client_id);
    RemoveLocked(c);
    ++live_expired_;
  }
  if (shared_) {
    std::vector<SharedJob> due;
    shared_->CutSilent(now, &due);
    QueueSharedLocked(&due);
  }
  return expired;
}

int64_t CollisionService::shared_published() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return shared_published_;
}

int64_t CollisionService::shared_published_messages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return shared_messages_;
}

int64_t CollisionService::shared_dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return shared_dropped_;
}

size_t CollisionService::shared_pending() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return shared_ ? shared_->pending() : 0;
}

int64_t CollisionService::publish_errors() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return publish_errors_;
}

int64_t CollisionService::ignored_after_stop() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ignored_after_stop_;
}

int64_t CollisionService::rejections_suppressed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return rejection_throttle_.suppressed_total();
}

int64_t CollisionService::rejected_unattributed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return rejected_unattributed_;
}

}  // namespace sweptccd
