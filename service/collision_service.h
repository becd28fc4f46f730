#pragma once
// The collision service: many tracked clients, one static environment, a pool
// of worker threads answering each client's consecutive pose pairs with the
// SPEC query and publishing contact events. Transport-free: poses come in
// through OnPose, everything goes out through an injected Publisher.

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/gpu/device_descent.h"
#include "core/query/ccd_query.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "msgs/signing.h"
#include "service/client_session.h"
#include "service/ops/latency_histogram.h"
#include "service/publisher.h"
#include "service/shared_world.h"
#include "service/token_bucket.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

/// One registered client (avatar).
struct ClientConfig {
  std::string client_id;                     // Non-empty, unique.
  std::shared_ptr<const Skeleton> skeleton;  // Non-null.
  MotionModel motion = MotionModel::kArticulated;
  CollisionFilter filter;  // Default: nothing ignored.
  /// Per-client tolerances (a live client's join): 0 takes ServiceOptions::query's.
  double eps_s = 0;
  double delta_m = 0;
  /// The shared world's filters of this avatar (SPEC 8 "Filters", resolved:
  /// link indices, -1 for "*"): a rule of either avatar applies to both
  /// avatars' answers for that pair of links.
  std::vector<world::EntityRule> entity_rules;
};

/// A tracked object (SPEC section 8): configured, never joined.
struct TrackedObjectConfig {
  std::string object_id;                    // Id rule; unique across clients and objects.
  std::shared_ptr<const Environment> mesh;  // One object, in the object's frame.
};

/// A live client's join (docs/SERVICE.md, "Live clients"), built off the
/// answering path by the daemon's join thread.
struct LiveJoinRequest {
  ClientConfig config;
  int64_t nonce = 0;
  std::array<uint8_t, kBoxPublicKeyBytes> public_key{};
  /// The join was proven with the id's own key (KeyRing::KeyFor: its
  /// security.client_keys entry, else the room key), as the WebSocket door
  /// proves every join: a configured id may then take a stream of its own
  /// (JoinLive). An LCM join is proven with the room key only: false.
  bool proven_with_client_key = false;
  /// `ignore` rules the join asked for (a configured client's are the
  /// configuration's: it may ask for none).
  size_t ignore_rules = 0;
};

/// The answer to a join: reason is a join_reply_t::REASON_* code.
struct LiveJoinOutcome {
  int8_t reason = join_reply_t::REASON_ACCEPTED;
  std::string message;        // One line; empty when accepted.
  int64_t session = 0;        // Accepted: the session the client must send.
  std::optional<MacKey> key;  // Accepted in signed mode: the session key.
};

/// One client of the room as viewers see it (the WebSocket door's `room`).
struct RoomClient {
  std::string client_id;
  bool live = false;  // Joined (else configured).
  std::shared_ptr<const Skeleton> skeleton;
  MotionModel motion = MotionModel::kArticulated;
};

struct ServiceOptions {
  int num_workers = 2;  // Worker threads, >= 1.
  /// eps, delta, per-link and work limits for every query. `motion` is taken
  /// from each client's ClientConfig instead.
  QueryOptions query;
  std::string backend = "cpu";  // Reported in status_t...
  /// ...unless this is set: asked at every status (the GPU backend reports
  /// "cpu (gpu failed: ...)" once its context is lost). May be empty.
  std::function<std::string()> backend_state;
  std::string renderer;  // Reported in status_t (GPU renderer string).
  /// Called once for each client's engine before queries start (the daemon
  /// attaches the GPU backend here); may be empty.
  std::function<void(CcdEngine*)> prepare_engine;
  /// Latencies (receive -> publish) kept per client for median and p99.
  int latency_window = 1024;
  /// Wall clock in microseconds for utime fields; default: system clock.
  std::function<int64_t()> clock_utime;
  /// Reported in status_t.security: "signed", or "unsigned" when poses are
  /// not authenticated (lab bench).
  std::string security = "signed";
  /// Horizon of the utime_jump rule per client stream (ClientSession), > 0.
  int64_t max_utime_jump_us = kDefaultMaxUtimeJumpUs;
  /// Input rate limit per client (a token bucket checked first in OnPose,
  /// before any validation or geometry): > 0 Hz, burst >= 1.
  double max_pose_rate_hz = 240;
  int pose_burst = 16;
  /// Rejections published per key (client id, "" for unattributed ones),
  /// burst, and the number of keys tracked apart (RejectionThrottle).
  double rejection_rate_hz = 10;
  int rejection_burst = 10;
  int rejection_max_keys = 1024;
  /// Live clients (joined over LCM) at most at once; 0: joins are refused.
  int max_live_clients = 0;
  /// A live client with no pose (nor join) for this long is dropped, ms, > 0.
  /// The same timeout ends the shared world's windows (docs/SERVICE.md
  /// "Shared world"): there is no second one.
  int64_t silence_timeout_ms = 5000;
  /// The shared world (SPEC 8 "Live"): every pair is also answered against
  /// every other client and tracked object (shared_contact_t). Off: only the
  /// environment part, and `objects` must be empty. Off by default.
  bool shared_world = false;
  std::vector<TrackedObjectConfig> objects;
  int shared_max_history = 4096;  // Samples kept per entity.
  int shared_max_pending = 4096;  // (pair, entity) entries waiting, in all.
  /// Input rate limit per tracked object (object_pose_t), as the per-client
  /// one: a token bucket per configured object checked first in
  /// OnObjectPose, before any validation or geometry: > 0 Hz, burst >= 1.
  double max_object_pose_rate_hz = 240;
  int object_pose_burst = 16;
  /// The device descent (docs/SERVICE.md "The device descent"; docs/GPU.md):
  /// when set, a worker takes the ready pairs of up to descent_max_batch
  /// clients at once, has the GPU clear their environment parts' free
  /// intervals in one batch, then answers and publishes them one by one on
  /// the CPU skipping those (the same answers). Null: one pair per worker
  /// turn, as always. Every client's engine is added to it.
  std::shared_ptr<gpu::DeviceDescent> device_descent;
  int descent_max_batch = 16;  // Pairs per batch, 1 to 4096.
  /// How long a worker may wait for more pairs to fill its batch, counted
  /// from its oldest pair's receipt, us, 0 to 100000. 0: a batch is what is
  /// ready when the worker takes it; a room with one client never waits.
  int64_t descent_gather_us = 0;
};

/// Owns the client sessions and the worker pool.
///
/// Threading: OnPose and OnUndecodable may be called from any one thread at a
/// time or several (they take a mutex only for bookkeeping and never wait on
/// geometry); rejections are published on the calling thread. Contact events
/// are published from worker threads; per client strictly in pose order, one
/// pair at a time. Status, WaitUntilIdle and Stop may be called from any
/// thread.
class CollisionService {
 public:
  /// Starts the workers. Throws InputError for bad configuration (no clients
  /// while max_live_clients is 0,
  /// a client_id breaking the id rule (1-64 of [A-Za-z0-9_.-]), a duplicate, null skeleton,
  /// num_workers < 1, invalid query options, latency_window < 1). `environment` and `publisher`
  /// must outlive the service.
  CollisionService(std::shared_ptr<const Environment> environment,
                   std::vector<ClientConfig> clients, ServiceOptions options, Publisher* publisher);
  /// Stop()s.
  ~CollisionService();

  CollisionService(const CollisionService&) = delete;
  CollisionService& operator=(const CollisionService&) = delete;

  /// Accepts or rejects one tracker pose. Never blocks on geometry. After
  /// Stop() poses are ignored (counted in ignored_after_stop).
  void OnPose(const tracker_pose_t& pose);

  /// A message on the pose channel that could not be decoded: publishes a
  /// "decode_error" rejection and counts it.
  void OnUndecodable(const std::string& channel, const std::string& problem,
                     const char* type = "sweptccd.tracker_pose_t");

  /// A tracked object's pose (bytes, id rule and mac checked by the
  /// transport): used, or refused with one rejection (unknown_object for an
  /// id that is no configured object; nothing else is touched). The
  /// object's rate limit comes first: a pose over it is shed unread
  /// (rate_limited, counted in status_t.object_poses_rate_limited).
  void OnObjectPose(const object_pose_t& pose);

  /// A pose refused by the transport before decoding (bad_client_id,
  /// bad_signature): publishes the rejection and counts it as unattributed
  /// (its sender is unknown). `client_id` must be empty or follow the id rule.
  void OnRefused(const std::string& client_id, const Rejection& rejection);

  /// Blocks until no pair is pending or in flight and every answer has been
  /// published. For tests and orderly shutdown.
  void WaitUntilIdle();

  /// Stops accepting poses, answers and publishes every pending and in-flight
  /// pair, then joins the workers. Idempotent.
  void Stop();

  /// Adds a live client (docs/SERVICE.md, "Live clients"): refused when the id
  /// is configured, live under another nonce or public key (id in use), or
  /// max_live_clients are live. A configured id joined with
  /// `proven_with_client_key` (the WebSocket door) is not added but given a
  /// stream of its own ("Configured clients through the WebSocket door"):
  /// its skeleton, motion and tolerances must be the configuration's and it
  /// asks for no filters; a new session, greater than any it had, so its
  /// older streams' poses become stale_session; refused as id in use while
  /// another nonce holds it and was heard within silence_timeout_ms. It
  /// counts against no live-client limit. The same id, nonce and public key while live
  /// answer the same session and key (a lost reply). Builds the client's
  /// engine without holding the lock workers need: never stalls answers.
  /// `fresh_key` (signed mode) becomes the session key of a new session.
  /// Thread-safe; the daemon calls it from its join thread only.
  LiveJoinOutcome JoinLive(LiveJoinRequest request, std::optional<MacKey> fresh_key);
  /// Ends a live client's session: true when `client_id` was live with that
  /// session (its pending pair is dropped; an in-flight one is published).
  /// For a configured client held with that session: releases the hold
  /// (the client stays; its poses are answered as before).
  bool LeaveLive(const std::string& client_id, int64_t session);
  /// Drops every live client silent (no pose, nor its join) for
  /// silence_timeout_ms before `now`; returns their ids.
  std::vector<std::string> ExpireSilent(SteadyClock::time_point now);
  /// Whether `client_id` is live now, and then its session key (if signed).
  bool LiveKey(const std::string& client_id, std::optional<MacKey>* key) const;
  /// Whether `client_id` is a configured client.
  bool IsConfigured(const std::string& client_id) const;
  int live_clients() const;
  /// Every client now (configured first, then live ones in join order).
  std::vector<RoomClient> RoomClients() const;
  /// Changes whenever a client joins, leaves or is dropped.
  int64_t room_version() const;
  /// This service's instance (status_t.instance): its start time, us.
  int64_t instance() const { return instance_; }

  /// A snapshot of the per-client counters and latencies.
  status_t Status() const;
  /// Publishes Status() through the publisher.
  void PublishStatus();
  /// Receive-to-publish latency of every pair answered since start, all
  /// clients (the room's Prometheus histogram, service/ops/).
  LatencyHistogram latency_histogram() const;

  /// Shared-world entries published (in shared_published_messages()
  /// messages), and (pair, entity) entries waiting.
  int64_t shared_published() const;
  int64_t shared_published_messages() const;
  size_t shared_pending() const;
  /// Due shared entries dropped unanswered because more than
  /// shared_max_pending waited for a worker (the workers were behind).
  int64_t shared_dropped() const;

  int64_t publish_errors() const;
  int64_t ignored_after_stop() const;
  /// Rejections not attributable to a registered client (unknown client,
  /// decode errors).
  int64_t rejected_unattributed() const;
  /// Rejections held back by the publication rate bound, all keys.
  int64_t rejections_suppressed() const;

 private:
  struct Client {
    ClientConfig config;
    bool live = false;             // Joined over LCM (else configured).
    bool removed = false;          // Left or expired (workers skip it).
    bool held = false;             // Configured, joined through the door (ClaimConfiguredLocked).
    int64_t assigned_session = 0;  // Live: the only session accepted; held: the join's.
    int64_t nonce = 0;             // Live or held: the join's nonce (live: and key).
    std::array<uint8_t, kBoxPublicKeyBytes> public_key{};
    std::optional<MacKey> key;           // Live, signed mode: the session key.
    SteadyClock::time_point last_heard;  // Live or held: the join or the latest pose.
    std::unique_ptr<CcdEngine> engine;
    // The device descent's index of `engine` (-1: none, or it refused it).
    std::shared_ptr<gpu::DeviceDescent> descent;
    int descent_engine = -1;
    ClientSession session;
    std::deque<double> latencies_us;  // Newest at the back.
    TokenBucket pose_bucket;          // Input rate limit.
    int64_t rate_limited = 0;         // Poses shed by pose_bucket.
    Client(ClientConfig c, const Environment& env, const ServiceOptions& options);
    ~Client();  // Forgets the engine in the device descent.
    Client(const Client&) = delete;
    Client& operator=(const Client&) = delete;
  };

  void WorkerLoop();
  // The worker's turn with the device descent on (lock held on entry and
  // exit): takes the ready pairs of up to descent_max_batch clients (waiting
  // at most descent_gather_us for more), clears them on the device in one
  // batch, then answers and publishes them one by one.
  void AnswerDescentBatch(std::unique_lock<std::mutex>* lock);
  // Under mutex_: the bookkeeping after a client's pair was published
  // (latencies, its session, the shared world's part, back in the queue).
  void FinishPairLocked(const std::shared_ptr<Client>& index, const PosePair& pair,
                        double latency_us);
  // Under mutex_: a configured client's join through the WebSocket door
  // (JoinLive): checked against its configuration, then a new session.
  LiveJoinOutcome ClaimConfiguredLocked(const LiveJoinRequest& request);
  // Due shared entries of one pair not yet taken by a worker: answered
  // together and published as one shared_contact_t (at most
  // shared_contact_t::MAX_ENTRIES entries).
  using PairKey = std::tuple<std::string, int64_t, int64_t, int64_t, int64_t>;
  struct SharedBatch {
    PairKey key;  // client_id, pair, seq0, seq1, utime1.
    std::vector<SharedJob> jobs;
  };
  // Under mutex_: hands due shared-world entries to the workers, each into
  // the open batch of its pair (a new one at the back when there is none or
  // it is full).
  void QueueSharedLocked(std::vector<SharedJob>* due);
  // Under mutex_: takes the oldest batch off the ready list.
  SharedBatch TakeSharedBatchLocked();
  // Off the lock: answers a batch and publishes its one message. Stops
  // early (after 500 us and one entry at least) when an environment part is
  // waiting;
  // returns how many entries, from the front, were answered and published.
  size_t AnswerSharedBatch(const SharedBatch& batch);
  // Whether nothing is ready or in flight (under mutex_).
  bool IdleLocked() const { return ready_.empty() && shared_ready_.empty() && in_flight_ == 0; }
  // Under mutex_: removes a client from the maps and the order.
  void RemoveLocked(const std::shared_ptr<Client>& client);
  // `clears`: what the device descent cleared of the pair (nullptr: none).
  contact_event_t Answer(const Client& client, const PosePair& pair, double queue_us,
                         const PairClears* clears = nullptr) const;
  // Publishes through the throttle, keyed by client_id when `attributed` (the
  // pose came from that registered client), else by "".
  void Reject(const std::string& client_id, int64_t seq, const Rejection& rejection,
              bool attributed);
  // Under mutex_: the rejection (if any) of a pose of the registered client
  // `index`, rate limit first; queues the client when a pair became ready.
  std::optional<Rejection> AdmitLocked(const std::shared_ptr<Client>& client,
                                       const tracker_pose_t& pose, int64_t receive_utime,
                                       SteadyClock::time_point receive_time);
  void LogRejection(const std::string& client_id, int64_t seq, const Rejection& rejection,
                    int64_t now_us);
  void SafePublish(const std::function<void()>& publish, const char* what);
  int64_t NowUtime() const;

  std::shared_ptr<const Environment> environment_;
  ServiceOptions options_;
  Publisher* publisher_;
  std::vector<std::shared_ptr<Client>> clients_;  // Configured in order, then live ones.
  std::map<std::string, std::shared_ptr<Client>> client_index_;
  std::set<std::string> configured_ids_;  // Immutable after construction.

  mutable std::mutex mutex_;
  std::condition_variable work_cv_;            // Workers wait for ready clients.
  std::condition_variable idle_cv_;            // WaitUntilIdle waits for quiescence.
  std::deque<std::shared_ptr<Client>> ready_;  // Clients with a pending pair, none in flight.
  std::unique_ptr<SharedWorld> shared_;        // Null when options_.shared_world is off.
  std::list<SharedBatch> shared_ready_;        // Due shared entries by pair, oldest first.
  std::map<PairKey, std::list<SharedBatch>::iterator> shared_open_;  // Not full, not taken.
  size_t shared_ready_entries_ = 0;                                  // Entries in shared_ready_.
  world::EntityQueryOptions entity_options_;
  int64_t shared_published_ = 0;   // Entries.
  int64_t shared_messages_ = 0;    // shared_contact_t published.
  int64_t shared_by_timeout_ = 0;  // Entries published ended_by_timeout.
  int64_t shared_dropped_ = 0;
  struct ObjectInput {
    TokenBucket bucket;
    int64_t rate_limited = 0;
  };
  std::map<std::string, ObjectInput> object_inputs_;  // Configured objects (fixed keys).
  int64_t object_poses_received_ = 0;  // Decoded and verified, including refused ones.
  int64_t object_poses_rejected_ = 0;  // Refused (not counting rate_limited).
  int64_t object_poses_rate_limited_ = 0;
  int64_t room_version_ = 0;  // Bumped by every join and removal.
  int64_t last_session_ = 0;  // Sessions handed out are strictly increasing.
  int64_t live_joined_ = 0, live_left_ = 0, live_expired_ = 0;
  int64_t instance_ = 0;  // status_t.instance.
  int in_flight_ = 0;
  bool stopping_ = false;
  int64_t publish_errors_ = 0;
  int64_t ignored_after_stop_ = 0;
  int64_t rejected_unattributed_ = 0;
  RejectionThrottle rejection_throttle_;  // Under mutex_.
  LatencyHistogram latency_histogram_;    // Under mutex_.
  int64_t rejection_log_window_start_us_ = 0;
  int rejection_logs_in_window_ = 0;
  int64_t rejection_logs_suppressed_ = 0;

  std::mutex stop_mutex_;  // Serialises Stop().
  std::vector<std::thread> workers_;
};

}  // namespace sweptccd
