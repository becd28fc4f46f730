#include "service/daemon/daemon.h"

#include <fcntl.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <thread>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "service/collision_service.h"
#include "service/lcm_transport.h"

namespace sweptccd {

namespace {

using Clock = std::chrono::steady_clock;

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
std::unique_ptr<gpu::Backend> MakeBackend(const ServiceConfig& config) {
  gpu::BackendOptions options;
  options.backend = config.backend;
  options.device_index = config.gpu_device;
  options.require_hardware = config.require_hardware;
  auto backend = std::make_unique<gpu::Backend>(options);
  if (config.backend == gpu::BackendKind::kGpu && !backend->gpu()) {
    spdlog::error("backend {}", backend->reason());
  } else {
    spdlog::info("backend {}", backend->reason());
  }
  return backend;
}

ServiceOptions OptionsFor(const ServiceConfig& config, gpu::Backend* backend) {
  ServiceOptions options;
  options.num_workers = config.workers;
  options.query = config.query;
  options.backend = backend->name();
  options.backend_state = [backend] { return backend->State(); };
  options.renderer = backend->renderer();
  options.prepare_engine = [backend](CcdEngine* engine) { backend->Attach(engine); };
  options.security = config.security.mode;
  options.max_utime_jump_us = static_cast<int64_t>(config.security.max_utime_jump_s * 1e6);
  options.max_pose_rate_hz = config.max_pose_rate_hz;
  return options;
}

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
  std::unique_ptr<gpu::Backend> backend;  // Outlives the service (its engines use it).
  std::unique_ptr<lcm::LCM> lcm;
  std::unique_ptr<LcmTransport> transport;  // Outlives the service (its publisher).
  std::unique_ptr<CollisionService> service;
  int control[2] = {-1, -1};
  std::thread loop;

  std::mutex mutex;
  std::condition_variable drained_cv;
  int64_t drains_requested = 0;
  int64_t drains_done = 0;
  bool running = false;
  std::mutex stop_mutex;  // Serialises Stop().
  bool stopped = false;
};

Daemon::Impl::Impl(const ServiceConfig& c) : config(c) {
  SetLogLevel(config.log_level);
  // Key files first: a bad key is refused before the environment loads.
  TransportSecurity security = LoadTransportSecurity(config.security);
  std::shared_ptr<const Environment> env = LoadEnvironment(config);
  std::vector<ClientConfig> clients = LoadClients(config, *env);
  // No pose may claim more links than the largest configured skeleton.
  security.limits.max_links = 1;
  for (const ClientConfig& cc : clients) {
    security.limits.max_links = std::max(security.limits.max_links, cc.skeleton->num_links());
  }
  backend = MakeBackend(config);
  lcm = std::make_unique<lcm::LCM>(config.lcm_url);
  if (!lcm->good()) throw InputError("--lcm-url '" + config.lcm_url + "': LCM cannot open it");
  if (!security.signed_mode) {
    spdlog::warn("UNSIGNED MODE: poses are not authenticated and what this service publishes is "
                 "not signed; anyone on the network can forge or replay them. Lab bench only.");
  }
  transport = std::make_unique<LcmTransport>(lcm.get(), config.channels, std::move(security));
  service = std::make_unique<CollisionService>(env, std::move(clients),
                                               OptionsFor(config, backend.get()), transport.get());
  if (pipe2(control, O_CLOEXEC) != 0) {
    throw InputError(std::string("cannot create the daemon's control pipe: ") +
                     std::strerror(errno));
  }
  transport->Subscribe(service.get());
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
  auto next_status = Clock::now() + period;
  for (;;) {
    const auto now = Clock::now();
    if (now >= next_status) {
      service->PublishStatus();
      next_status += period;
      if (next_status < now) next_status = now + period;
      continue;
    }
    const int timeout_ms = static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(next_status - now).count() + 1);
    pollfd fds[2] = {{lcm->getFileno(), POLLIN, 0}, {control[0], POLLIN, 0}};
    if (poll(fds, 2, timeout_ms) < 0) {
      if (errno == EINTR) continue;
      spdlog::error("the daemon's loop stops: poll failed: {}", std::strerror(errno));
      break;
    }
    if ((fds[1].revents & POLLIN) && !HandleControl()) break;
    if (fds[0].revents & POLLIN) lcm->handleTimeout(0);
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

void Daemon::Start() {
  std::lock_guard<std::mutex> stop_lock(impl_->stop_mutex);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  SWEPTCCD_CHECK(!impl_->loop.joinable() && !impl_->stopped);
  impl_->running = true;
  impl_->loop = std::thread([impl = impl_.get()] { impl->Loop(); });
  const ServiceConfig& c = impl_->config;
  spdlog::info("ready: {} clients, {} workers, listening on '{}' channel {}", c.clients.size(),
               c.workers, c.lcm_url, c.channels.pose);
}

void Daemon::WaitUntilIdle() {
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
  impl_->service->Stop();
  impl_->service->PublishStatus();
  spdlog::info("stopped");
}

lcm::LCM* Daemon::lcm() { return impl_->lcm.get(); }

CollisionService* Daemon::service() { return impl_->service.get(); }

}  // namespace sweptccd
