#include "service/daemon/daemon.h"

#include <fcntl.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <deque>
#include <filesystem>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/avatar/link_key.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/worker_pool.h"
#include "msgs/text.h"
#include "service/collision_service.h"
#include "service/fanout_publisher.h"
#include "service/lcm_transport.h"
#include "service/ops/prometheus_text.h"
#include "service/ops/room_name.h"
#include "service/ws/door.h"

namespace sweptccd {

namespace {

// The live view's files when --ws-view-dir is not given: the installed bundle
// beside the executable (PREFIX/bin -> PREFIX/share/sweptccd/view), else the
// build tree's (<build>/view).
std::string DefaultViewDir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed =
        exe.parent_path().parent_path() / "share" / "sweptccd" / "view";
    if (std::filesystem::is_directory(installed, ec)) return installed.string();
  }
  return SWEPTCCD_DEFAULT_VIEW_DIR;
}

using Clock = std::chrono::steady_clock;

// LCM messages handled per wake-up of the loop at most: a tick's burst of
// poses (one per client) is handled without a poll() and a clock read
// between messages, and a flood still lets the control pipe and the timers
// in after at most this many.
constexpr int kMaxMessagesPerWake = 64;

// Bytes on the loop's control pipe.
constexpr char kDrain = 'd';  // Handle everything queued, then report.
constexpr char kQuit = 'q';   // Leave the loop.

void SetLogLevel(const std::string& name) {
  const auto level = spdlog::level::from_str(name);
  if (level == spdlog::level::off && name != "off") {
    throw InputError("configuration: unknown log_level '" + name +
                     "'; use trace, debug, info, warn, error or off");
  }
  spdlog::set_level(level);
}

std::shared_ptr<const Environment> LoadEnvironment(const ServiceConfig& config) {
  const auto t0 = Clock::now();
  auto env = std::make_shared<Environment>(Environment::LoadFiles(
      config.environment, MeshLoadOptions{config.max_mesh_bytes, kDefaultMaxMeshLineBytes}));
  spdlog::info("environment: {} objects, {} triangles, loaded in {:.3f} s", env->num_objects(),
               env->num_triangles(), std::chrono::duration<double>(Clock::now() - t0).count());
  return env;
}

// What a shared-world filter's other entity can be resolved against: the
// configured clients' skeletons (a live client's skeleton may differ at its
// next join, so its links are given by index or "*") and the tracked objects
// (no links).
struct RuleTargets {
  std::map<std::string, std::shared_ptr<const Skeleton>> skeletons;
  std::set<std::string> objects;
};

RuleTargets RuleTargetsOf(const ServiceConfig& config, const std::vector<ClientConfig>& clients) {
  RuleTargets t;
  for (const ClientConfig& c : clients) t.skeletons[c.client_id] = c.skeleton;
  for (const ObjectSpec& o : config.objects) t.objects.insert(o.id);
  return t;
}

// One filter rule of an avatar with skeleton `own`, resolved (SPEC 8
// "Filters"). Throws InputError naming `where` and the problem.
world::EntityRule ResolveEntityRule(const EntityRuleSpec& r, const Skeleton& own,
                                    const RuleTargets& targets, const std::string& where) {
  if (!IsValidClientId(r.entity)) {
    throw InputError(where + ".entity: '" + EscapeForDisplay(r.entity) +
                     "' breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)");
  }
  world::EntityRule rule;
  rule.link = ResolveLinkKey(r.link, own, where + ".link");  // Or kAllLinks.
  rule.entity = r.entity;
  if (r.other_link.empty()) return rule;
  if (targets.objects.count(r.entity)) {
    throw InputError(where + ": other_link given for object '" + r.entity +
                     "' (objects have no links)");
  }
  const auto other = targets.skeletons.find(r.entity);
  if (other != targets.skeletons.end()) {
    rule.other_link = ResolveLinkKey(r.other_link, *other->second, where + ".other_link");
  } else if (const std::optional<LinkIndex> index = LinkKeyWithoutNames(r.other_link)) {
    rule.other_link = *index;
  } else {
    throw InputError(where + ".other_link: '" + EscapeForDisplay(r.other_link) +
                     "' names a link of '" + r.entity +
                     "', which is not a configured client; give an index or \"*\"");
  }
  return rule;
}

// The shared world's filters of every configured client, resolved against
// the skeletons.
void ResolveEntityRules(const ServiceConfig& config, const RuleTargets& targets,
                        std::vector<ClientConfig>* clients) {
  for (size_t i = 0; i < clients->size(); ++i) {
    ClientConfig& cc = (*clients)[i];
    const std::vector<EntityRuleSpec>& specs = config.clients[i].ignore_entities;
    for (size_t k = 0; k < specs.size(); ++k) {
      const std::string where = "configuration: clients[" + std::to_string(i) + "] ('" +
                                cc.client_id + "') ignore_entities[" + std::to_string(k) + "]";
      cc.entity_rules.push_back(ResolveEntityRule(specs[k], *cc.skeleton, targets, where));
    }
  }
}

std::vector<ClientConfig> LoadClients(const ServiceConfig& config, const Environment& env) {
  std::vector<ClientConfig> clients;
  for (const ClientSpec& spec : config.clients) {
    ClientConfig cc;
    cc.client_id = spec.id;
    cc.skeleton =
        std::make_shared<const Skeleton>(LoadSkeletonFile(spec.skeleton_path, config.max_links));
    cc.motion = spec.motion;
    cc.filter = CollisionFilter(cc.skeleton->num_links(), env.num_objects());
    if (!spec.filter_path.empty()) {
      cc.filter = CollisionFilter::FromFile(spec.filter_path, *cc.skeleton, env);
    }
    for (const std::string& rule : spec.ignore_rules) cc.filter.AddRule(rule, *cc.skeleton, env);
    clients.push_back(std::move(cc));
  }
  return clients;
}

// One headless context for the daemon's life; the environment is uploaded
// once and every client's engine tests against it.
// auto: calibrated on the environment with the first configured client's
// skeleton and filter (a one-capsule skeleton when there is none).
std::unique_ptr<gpu::Backend> MakeBackend(const ServiceConfig& config, const Environment& env,
                                          const std::vector<ClientConfig>& clients) {
  gpu::BackendOptions options;
  options.backend = config.backend;
  options.device_index = config.gpu_device;
  options.require_hardware = config.require_hardware;
  auto backend = std::make_unique<gpu::Backend>(options);
  const ClientConfig* first = clients.empty() ? nullptr : &clients.front();
  backend->ResolveAuto(env, first ? first->skeleton.get() : nullptr,
                       first ? &first->filter : nullptr, config.query);
  if (config.backend == gpu::BackendKind::kGpu && !backend->gpu()) {
    spdlog::error("backend {}", backend->reason());
  } else {
    spdlog::info("backend {}", backend->reason());
  }
  return backend;
}

ServiceOptions OptionsFor(const ServiceConfig& config, const Environment& env,
                          gpu::Backend* backend) {
  ServiceOptions options;
  options.num_workers = config.workers;
  options.query = config.query;
  options.backend = backend->name();
  options.backend_state = [backend] { return backend->State(); };
  options.renderer = backend->renderer();
  // The device descent (docs/SERVICE.md): the GPU clears each gathered
  // batch's free intervals and the CPU engines answer (no culler attached);
  // a descent that cannot be made leaves the GPU backend as it was.
  if (config.device_descent && backend->gpu()) {
    gpu::DescentOptions descent_options;
    // Its preparation on as many threads as workers, no more than the cores
    // (each thread is started once, for the daemon's life).
    descent_options.host_threads = std::min(config.workers, DefaultThreadCount());
    options.device_descent = backend->MakeDescent(env, descent_options);
  } else if (config.device_descent) {
    spdlog::warn("device_descent is ignored: the backend is the CPU");
  }
  options.descent_max_batch = config.descent_max_batch;
  options.descent_gather_us = config.descent_gather_us;
  if (options.device_descent != nullptr) {
    spdlog::info("device descent on: batches of up to {} pairs, gather window {} us",
                 config.descent_max_batch, config.descent_gather_us);
  } else {
    options.prepare_engine = [backend](CcdEngine* engine) { backend->Attach(engine); };
  }
  options.security = config.security.mode;
  options.max_utime_jump_us = static_cast<int64_t>(config.security.max_utime_jump_s * 1e6);
  options.max_pose_rate_hz = config.max_pose_rate_hz;
  options.max_object_pose_rate_hz = config.max_object_pose_rate_hz;
  options.max_live_clients = config.max_live_clients;
  options.silence_timeout_ms = config.silence_timeout_ms;
  options.shared_world = config.shared_world;
  for (const ObjectSpec& spec : config.objects) {
    auto mesh = std::make_shared<Environment>();
    try {
      mesh->AddMesh(LoadMeshFile(spec.mesh_path,
                                 MeshLoadOptions{config.max_mesh_bytes, kDefaultMaxMeshLineBytes}),
                    spec.mesh_path);
    } catch (const InputError& e) {
      // Which object's mesh: the file alone may serve several.
      throw InputError("objects: '" + spec.id + "' mesh: " + e.what());
    }
    options.objects.push_back({spec.id, std::move(mesh)});
  }
  return options;
}

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Joins waiting for the join thread at most; more are answered "busy".
constexpr size_t kMaxQueuedJoins = 16;

using JoinReplyFn = std::function<void(const join_reply_t&)>;

// Live clients (docs/SERVICE.md, "Live clients"): joins are checked and
// queued on the LCM thread (or the WebSocket door's), then built (skeleton,
// filter, engine) and answered on the join thread, never on a worker nor
// under the lock workers take; leaves are handled at once (cheap).
class LiveRegistry : public LiveSessionHandler {
 public:
  LiveRegistry(const ServiceConfig& config, std::shared_ptr<const Environment> env,
               RuleTargets rule_targets, CollisionService* service, LcmTransport* transport,
               bool signed_mode)
      : config_(config),
        env_(std::move(env)),
        rule_targets_(std::move(rule_targets)),
        service_(service),
        transport_(transport),
        signed_mode_(signed_mode),
        max_utime_jump_us_(static_cast<int64_t>(config.security.max_utime_jump_s * 1e6)) {
    thread_ = std::thread([this] { Run(); });
  }
  ~LiveRegistry() override { Stop(); }

  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  void OnJoinRequest(join_request_t request) override { Submit({std::move(request), {}}); }

  // A join through the WebSocket door (docs/WEBSOCKET.md): the same queue,
  // checks and service; in signed mode the session key is a fresh random
  // key that stays in the service (the connection is the session), and the
  // answer goes to `reply` instead of LCM.
  void SubmitDoorJoin(join_request_t request, JoinReplyFn reply) {
    Submit({std::move(request), std::move(reply)});
  }

  void OnLeave(const leave_t& leave) override {
    if (service_->LeaveLive(leave.client_id, leave.session)) {
      spdlog::info("live client '{}' left (session {})", leave.client_id, leave.session);
    } else {
      spdlog::info("leave of client '{}' session {} ignored: not that live session",
                   leave.client_id, leave.session);
    }
  }

  // Blocks until every join queued before the call has been answered.
  void WaitUntilIdle() {
    std::unique_lock<std::mutex> lock(mutex_);
    const int64_t target = queued_;
    idle_cv_.wait(lock, [&] { return answered_ >= target || stopping_; });
  }

 private:
  // A queued join: `reply` set for the WebSocket door's (door keyed).
  struct PendingJoin {
    join_request_t request;
    JoinReplyFn reply;
  };

  void Submit(PendingJoin join) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!stopping_ && queue_.size() < kMaxQueuedJoins) {
        queue_.push_back(std::move(join));
        ++queued_;
        cv_.notify_one();
        return;
      }
    }
    Reply(join, {join_reply_t::REASON_BUSY,
                 std::to_string(kMaxQueuedJoins) + " joins are waiting already; join again "
                                                   "in a moment",
                 0,
                 {}});
  }

  void Run() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) break;
      PendingJoin join = std::move(queue_.front());
      queue_.pop_front();
      lock.unlock();
      try {
        Handle(join);
      } catch (const std::exception& e) {
        spdlog::error("join of client '{}': {}", EscapeForDisplay(join.request.client_id),
                      e.what());
      }
      lock.lock();
      ++answered_;
      idle_cv_.notify_all();
    }
    idle_cv_.notify_all();
  }

  LiveJoinOutcome Refuse(int8_t reason, std::string message) {
    return {reason, std::move(message), 0, {}};
  }

  // Everything SPEC section 1 and the limits ask of a join, then the service.
  LiveJoinOutcome Decide(const join_request_t& r, bool door_keyed) {
    const int64_t skew = r.utime - WallUtime();
    if (skew > max_utime_jump_us_ || -skew > max_utime_jump_us_) {
      return Refuse(join_reply_t::REASON_STALE_REQUEST,
                    "join utime " + std::to_string(r.utime) + " is " + std::to_string(skew / 1000) +
                        " ms off the daemon's clock (limit " +
                        std::to_string(max_utime_jump_us_ / 1000) +
                        " ms, security.max_utime_jump_s); sync the clocks and join again");
    }
    if (r.num_links > config_.max_links) {
      return Refuse(join_reply_t::REASON_TOO_MANY_LINKS,
                    "the skeleton has " + std::to_string(r.num_links) +
                        " links, over this daemon's max_links " +
                        std::to_string(config_.max_links) + "; send a smaller skeleton");
    }
    ClientConfig cc;
    cc.client_id = r.client_id;
    if (r.motion == join_request_t::MOTION_ARTICULATED) {
      cc.motion = MotionModel::kArticulated;
    } else if (r.motion == join_request_t::MOTION_INDEPENDENT) {
      cc.motion = MotionModel::kIndependent;
    } else {
      return Refuse(join_reply_t::REASON_BAD_OPTIONS,
                    "motion " + std::to_string(r.motion) +
                        " is not MOTION_ARTICULATED (0) or MOTION_INDEPENDENT (1)");
    }
    QueryOptions q = config_.query;
    if (r.eps_s != 0) q.eps_s = r.eps_s;
    if (r.delta_m != 0) q.delta_m = r.delta_m;
    if (const std::string problem = ValidateQueryOptions(q); !problem.empty()) {
      return Refuse(join_reply_t::REASON_BAD_OPTIONS, "tolerances: " + problem);
    }
    cc.eps_s = r.eps_s;
    cc.delta_m = r.delta_m;
    std::vector<Link> links(static_cast<size_t>(r.num_links));
    for (int i = 0; i < r.num_links; ++i) {
      Link& l = links[static_cast<size_t>(i)];
      l.name = r.link_name[i];
      if (r.parent[i] < -1 || r.parent[i] >= r.num_links) {
        return Refuse(join_reply_t::REASON_BAD_SKELETON,
                      "link " + std::to_string(i) + " ('" + EscapeForDisplay(l.name) +
                          "') has parent index " + std::to_string(r.parent[i]) + ", outside [-1, " +
                          std::to_string(r.num_links) + ")");
      }
      l.parent = r.parent[i];
      l.a_L = Eigen::Vector3d(r.a[i][0], r.a[i][1], r.a[i][2]);
      l.b_L = Eigen::Vector3d(r.b[i][0], r.b[i][1], r.b[i][2]);
      l.radius = r.radius[i];
    }
    try {
      cc.skeleton = std::make_shared<const Skeleton>(
          Skeleton::FromLinks(r.client_id, std::move(links), "join of '" + r.client_id + "'"));
    } catch (const InputError& e) {
      return Refuse(join_reply_t::REASON_BAD_SKELETON, EscapeForDisplay(e.what(), 400));
    }
    cc.filter = CollisionFilter(cc.skeleton->num_links(), env_->num_objects());
    for (const std::string& rule : r.ignore) {
      try {
        cc.filter.AddRule(rule, *cc.skeleton, *env_);
      } catch (const InputError& e) {
        return Refuse(join_reply_t::REASON_BAD_FILTER, EscapeForDisplay(e.what(), 400));
      }
    }
    if (r.num_ignore_entities > 0 && !config_.shared_world) {
      return Refuse(join_reply_t::REASON_BAD_FILTER,
                    "ignore_entity rules need the shared world, and this daemon runs without "
                    "it (shared_world: false)");
    }
    for (int32_t k = 0; k < r.num_ignore_entities; ++k) {
      const EntityRuleSpec spec{r.ignore_entity_link[k], r.ignore_entity[k],
                                r.ignore_entity_other_link[k]};
      try {
        cc.entity_rules.push_back(ResolveEntityRule(spec, *cc.skeleton, rule_targets_,
                                                    "ignore_entity rule " + std::to_string(k)));
      } catch (const InputError& e) {
        return Refuse(join_reply_t::REASON_BAD_FILTER, EscapeForDisplay(e.what(), 400));
      }
    }
    std::optional<MacKey> key;
    if (signed_mode_) {
      bool zero = true;
      for (uint8_t b : r.public_key) zero = zero && b == 0;
      if (zero && !door_keyed) {
        return Refuse(join_reply_t::REASON_BAD_OPTIONS,
                      "signed mode: the join carries no public_key to seal the session key to");
      }
      key = NewRandomKey();
    }
    LiveJoinRequest request;
    request.config = std::move(cc);
    request.nonce = r.nonce;
    std::copy(std::begin(r.public_key), std::end(r.public_key), request.public_key.begin());
    // The door proves every join with the id's own key (KeyRing::KeyFor);
    // an LCM join with the room key.
    request.proven_with_client_key = door_keyed;
    request.ignore_rules = r.ignore.size();
    return service_->JoinLive(std::move(request), std::move(key));
  }

  void Handle(const PendingJoin& join) {
    const join_request_t& r = join.request;
    const LiveJoinOutcome outcome = Decide(r, static_cast<bool>(join.reply));
    if (outcome.reason == join_reply_t::REASON_ACCEPTED) {
      spdlog::info("{} client '{}' joined: session {}, {} links",
                   service_->IsConfigured(r.client_id) ? "configured" : "live", r.client_id,
                   outcome.session, r.num_links);
    } else {
      spdlog::info("join of client '{}' refused ({}): {}", EscapeForDisplay(r.client_id),
                   static_cast<int>(outcome.reason), EscapeForDisplay(outcome.message, 400));
    }
    Reply(join, outcome);
  }

  void Reply(const PendingJoin& join, const LiveJoinOutcome& outcome) {
    const join_request_t& r = join.request;
    join_reply_t reply;
    reply.utime = WallUtime();
    reply.client_id = r.client_id;
    reply.nonce = r.nonce;
    reply.reason = outcome.reason;
    reply.message = outcome.message;
    reply.session = outcome.session;
    reply.instance = service_->instance();
    reply.silence_timeout_ms = config_.silence_timeout_ms;
    if (outcome.reason == join_reply_t::REASON_ACCEPTED && outcome.key && !join.reply) {
      try {
        reply.sealed_key = SealKey(*outcome.key, r.public_key);
      } catch (const std::exception& e) {
        // Not a valid X25519 key: the session stays until silence drops it.
        reply.reason = join_reply_t::REASON_BAD_OPTIONS;
        reply.message = "public_key: " + std::string(e.what());
        reply.session = 0;
      }
    }
    reply.sealed_key_size = static_cast<int32_t>(reply.sealed_key.size());
    try {
      if (join.reply) {
        join.reply(reply);
        return;
      }
      transport_->PublishJoinReply(reply);
    } catch (const std::exception& e) {
      spdlog::error("publishing a join reply failed: {}", e.what());
    }
  }

  const ServiceConfig& config_;
  std::shared_ptr<const Environment> env_;
  const RuleTargets rule_targets_;
  CollisionService* service_;
  LcmTransport* transport_;
  bool signed_mode_;
  int64_t max_utime_jump_us_;
  std::mutex mutex_;
  std::condition_variable cv_, idle_cv_;
  std::deque<PendingJoin> queue_;
  int64_t queued_ = 0, answered_ = 0;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace

struct Daemon::Impl {
  explicit Impl(const ServiceConfig& c);
  ~Impl();
  void Loop();
  bool HandleControl();  // False: quit.
  void Drain();
  void Barrier();
  void Send(char byte);

  ServiceConfig config;
  RoomName room;  // config.ops.room, then the Agones label (service/ops/room_name.h).
  std::unique_ptr<gpu::Backend> backend;        // Outlives the service (its engines use it).
  std::shared_ptr<gpu::DeviceDescent> descent;  // The service's; null when off.
  std::unique_ptr<lcm::LCM> lcm;
  std::unique_ptr<LcmTransport> transport;     // Outlives the service (its publisher).
  std::unique_ptr<FanoutPublisher> publisher;  // LCM, then the door: the service's.
  std::unique_ptr<CollisionService> service;
  std::unique_ptr<LiveRegistry> live;  // Stopped before the service.
  std::unique_ptr<WsDoor> door;        // Null without websocket.listen; destroyed first.
  int control[2] = {-1, -1};
  std::function<void()> tick;  // SetLoopTick's; empty: none.
  std::thread loop;

  std::mutex mutex;
  std::condition_variable drained_cv;
  int64_t drains_requested = 0;
  int64_t drains_done = 0;
  bool running = false;
  std::mutex stop_mutex;  // Serialises Stop().
  bool stopped = false;
};

Daemon::Impl::Impl(const ServiceConfig& c) : config(c), room(c.ops.room) {
  SetLogLevel(config.log_level);
  // Key files first: a bad key is refused before the environment loads.
  TransportSecurity security = LoadTransportSecurity(config.security);
  // A tracked object's own key (objects[].key) verifies its poses, as a
  // client's key does (one id space).
  if (security.signed_mode) {
    for (const ObjectSpec& o : config.objects) {
      if (!o.key_path.empty()) security.keys.SetClientKey(o.id, LoadKeyFile(o.key_path));
    }
  }
  std::shared_ptr<const Environment> env = LoadEnvironment(config);
  std::vector<ClientConfig> clients = LoadClients(config, *env);
  // Made once: the configured clients' filters and every live join's.
  RuleTargets rule_targets = RuleTargetsOf(config, clients);
  ResolveEntityRules(config, rule_targets, &clients);
  // No pose may claim more links than the largest configured skeleton.
  // With live clients: no more than max_links (what a join may ask for).
  security.limits.max_links = config.max_live_clients > 0 ? config.max_links : 1;
  for (const ClientConfig& cc : clients) {
    security.limits.max_links = std::max(security.limits.max_links, cc.skeleton->num_links());
  }
  security.limits.max_join_links = std::max(security.limits.max_join_links, config.max_links);
  const bool signed_mode = security.signed_mode;
  if (signed_mode && config.max_live_clients > 0 && security.keys.RoomKey() == nullptr) {
    spdlog::warn("no security.room_key: joins cannot be verified and are refused");
  }
  backend = MakeBackend(config, *env, clients);
  lcm = std::make_unique<lcm::LCM>(config.lcm_url);
  if (!lcm->good()) throw InputError("--lcm-url '" + config.lcm_url + "': LCM cannot open it");
  if (!security.signed_mode) {
    spdlog::warn(
        "UNSIGNED MODE: poses are not authenticated and what this service publishes is "
        "not signed; anyone on the network can forge or replay them. Lab bench only.");
  }
  // The door's copies (the transport takes the originals).
  const KeyRing door_keys = security.keys;
  const WireLimits door_limits = security.limits;
  transport = std::make_unique<LcmTransport>(lcm.get(), config.channels, std::move(security));
  publisher = std::make_unique<FanoutPublisher>(transport.get());
  ServiceOptions service_options = OptionsFor(config, *env, backend.get());
  descent = service_options.device_descent;
  std::vector<ws::SceneObject> scene_objects;
  for (const TrackedObjectConfig& o : service_options.objects) {
    scene_objects.push_back({o.object_id, o.mesh});
  }
  service = std::make_unique<CollisionService>(env, std::move(clients), std::move(service_options),
                                               publisher.get());
  if (pipe2(control, O_CLOEXEC) != 0) {
    throw InputError(std::string("cannot create the daemon's control pipe: ") +
                     std::strerror(errno));
  }
  transport->Subscribe(service.get());
  live = std::make_unique<LiveRegistry>(config, env, std::move(rule_targets), service.get(),
                                        transport.get(), signed_mode);
  transport->SubscribeLive(live.get());
  if (!config.websocket.listen.empty()) {
    WsDoorOptions options = config.websocket;
    if (options.view_dir.empty()) options.view_dir = DefaultViewDir();
    WsDoorContext ctx;
    ctx.service = service.get();
    ctx.room = &room;
    ctx.signed_mode = signed_mode;
    ctx.keys = door_keys;
    ctx.limits = door_limits;
    ctx.silence_timeout_ms = config.silence_timeout_ms;
    ctx.status_period_ms = static_cast<int64_t>(std::ceil(config.status_period_s * 1000));
    ctx.max_pose_rate_hz = config.max_pose_rate_hz;
    ctx.pose_burst = ServiceOptions().pose_burst;
    ctx.shared_world = config.shared_world;
    for (const ObjectSpec& o : config.objects) ctx.tracked_objects.push_back(o.id);
    const auto t0 = Clock::now();
    ctx.scene = ws::BuildScene(*env, scene_objects, options.max_scene_triangles);
    spdlog::info("websocket scene: {} meshes for display, built in {:.3f} s",
                 ctx.scene.meshes.size(), std::chrono::duration<double>(Clock::now() - t0).count());
    LiveRegistry* registry = live.get();
    CollisionService* svc = service.get();
    const RoomName* room_name = &room;
    ctx.metrics = [svc, room_name] {
      return RenderRoomMetrics(room_name->Get(), svc->Status(), svc->latency_histogram());
    };
    ctx.submit_join = [registry](join_request_t request, JoinReplyFn reply) {
      registry->SubmitDoorJoin(std::move(request), std::move(reply));
    };
    door = std::make_unique<WsDoor>(std::move(options), std::move(ctx));
    publisher->SetSecond(door.get());
  }
}

Daemon::Impl::~Impl() {
  for (int fd : control) {
    if (fd >= 0) close(fd);
  }
}

void Daemon::Impl::Send(char byte) {
  for (;;) {
    const ssize_t n = write(control[1], &byte, 1);
    if (n == 1) return;
    SWEPTCCD_CHECK(n < 0 && errno == EINTR);
  }
}

void Daemon::Impl::Drain() {
  while (lcm->handleTimeout(0) > 0) {
  }
}

bool Daemon::Impl::HandleControl() {
  char bytes[64];
  const ssize_t n = read(control[0], bytes, sizeof(bytes));
  bool quit = false;
  for (ssize_t i = 0; i < n; ++i) {
    if (bytes[i] == kQuit) quit = true;
    if (bytes[i] != kDrain) continue;
    Drain();
    std::lock_guard<std::mutex> lock(mutex);
    ++drains_done;
    drained_cv.notify_all();
  }
  return !quit;
}

void Daemon::Impl::Loop() {
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.status_period_s));
  // The first status at once: a restarted daemon announces its new instance.
  auto next_status = Clock::now();
  // Silence is checked 8 times per timeout (a client is dropped between
  // silence_timeout_ms and 9/8 of it after its last pose).
  const auto expiry_period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::milliseconds(std::max<int64_t>(1, config.silence_timeout_ms / 8)));
  auto next_expiry = Clock::now() + expiry_period;
  // With a tick, the loop wakes at least this often.
  constexpr auto kTickPeriod = std::chrono::milliseconds(250);
  for (;;) {
    if (tick) tick();
    const auto now = Clock::now();
    if (now >= next_expiry) {
      for (const std::string& id : service->ExpireSilent(now)) {
        spdlog::info("live client '{}' dropped: no pose for {} ms (silence_timeout_ms)", id,
                     config.silence_timeout_ms);
      }
      next_expiry = now + expiry_period;
    }
    if (now >= next_status) {
      service->PublishStatus();
      next_status += period;
      if (next_status < now) next_status = now + period;
      continue;
    }
    auto next = std::min(next_status, next_expiry);
    if (tick) next = std::min<Clock::time_point>(next, now + kTickPeriod);
    const int timeout_ms = static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1);
    pollfd fds[2] = {{lcm->getFileno(), POLLIN, 0}, {control[0], POLLIN, 0}};
    if (poll(fds, 2, timeout_ms) < 0) {
      if (errno == EINTR) continue;
      spdlog::error("the daemon's loop stops: poll failed: {}", std::strerror(errno));
      break;
    }
    if ((fds[1].revents & POLLIN) && !HandleControl()) break;
    if (fds[0].revents & POLLIN) {
      for (int i = 0; i < kMaxMessagesPerWake && lcm->handleTimeout(0) > 0; ++i) {
      }
    }
  }
  std::lock_guard<std::mutex> lock(mutex);
  running = false;
  drained_cv.notify_all();
}

void Daemon::Impl::Barrier() {
  std::unique_lock<std::mutex> lock(mutex);
  if (!running) {
    lock.unlock();
    Drain();  // No loop: the caller's thread handles what is queued.
    return;
  }
  const int64_t ticket = ++drains_requested;
  Send(kDrain);
  drained_cv.wait(lock, [&] { return drains_done >= ticket || !running; });
}

Daemon::Daemon(const ServiceConfig& config) : impl_(std::make_unique<Impl>(config)) {}

Daemon::~Daemon() { Stop(); }

void Daemon::SetLoopTick(std::function<void()> tick) {
  SWEPTCCD_CHECK(!impl_->loop.joinable());
  impl_->tick = std::move(tick);
}

void Daemon::Start() {
  std::lock_guard<std::mutex> stop_lock(impl_->stop_mutex);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  SWEPTCCD_CHECK(!impl_->loop.joinable() && !impl_->stopped);
  impl_->running = true;
  impl_->loop = std::thread([impl = impl_.get()] { impl->Loop(); });
  if (impl_->door) impl_->door->Start();
  const ServiceConfig& c = impl_->config;
  spdlog::info(
      "ready: {} clients, {} workers, listening on '{}' channel {}; up to {} live "
      "clients on {} (silence_timeout_ms {})",
      c.clients.size(), c.workers, c.lcm_url, c.channels.pose, c.max_live_clients, c.channels.join,
      c.silence_timeout_ms);
}

void Daemon::WaitUntilIdle() {
  impl_->Barrier();                 // Every join published before the call is queued...
  impl_->live->WaitUntilIdle();     // ...and answered...
  impl_->Barrier();                 // Every pose published before the call is handled...
  impl_->service->WaitUntilIdle();  // ...every pair answered and published...
  impl_->Barrier();                 // ...and every answer delivered to lcm()'s subscribers.
}

void Daemon::Stop() {
  std::lock_guard<std::mutex> stop_lock(impl_->stop_mutex);
  if (impl_->stopped) return;
  impl_->stopped = true;
  if (impl_->loop.joinable()) {
    impl_->Send(kQuit);
    impl_->loop.join();
  }
  spdlog::info("shutting down: finishing in-flight work");
  impl_->transport->Unsubscribe();
  impl_->live->Stop();
  impl_->service->Stop();
  impl_->service->PublishStatus();
  if (impl_->door) {
    impl_->door->Stop();
    impl_->publisher->SetSecond(nullptr);
  }
  // The GPU's dispatches over the run (tools/service_bench/backends.sh).
  if (impl_->descent != nullptr) {
    const gpu::DescentStats d = impl_->descent->stats();
    spdlog::info(
        "GPU device descent: {} batches, {} pairs, {} dispatches, {} intervals tested, {} "
        "cleared, {} pairs over budget; {}",
        d.batches, d.pairs, d.dispatches, d.items, d.cleared, d.over_budget, gpu::DescentTimes(d));
  } else if (impl_->backend && impl_->backend->gpu()) {
    spdlog::info("GPU: {}", impl_->backend->DispatchSummary());
  }
  spdlog::info("stopped");
}

lcm::LCM* Daemon::lcm() { return impl_->lcm.get(); }

CollisionService* Daemon::service() { return impl_->service.get(); }

RoomName* Daemon::room() { return &impl_->room; }

}  // namespace sweptccd
