#pragma once
// The collision daemon assembled from its configuration: the environment
// loaded once, every client's skeleton and filter, the query backend, the LCM
// adapter and the CollisionService, plus the loop that feeds LCM traffic to
// the service and publishes status on a timer. In the manner of
// Cartographer's cloud/ service: sweptccd-service's main only parses flags,
// builds a Daemon, Start()s it and waits for a stop signal; tests build one on
// memq:// and use WaitUntilIdle instead of sleeps.

#include <functional>
#include <memory>

#include "service/service_config.h"

namespace lcm {
class LCM;
}  // namespace lcm

namespace sweptccd {

class CollisionService;
class RoomName;

class Daemon {
 public:
  /// Builds everything `config` names and subscribes to the pose channel;
  /// nothing is handled until Start(). `config` must be valid
  /// (ValidateServiceConfig). Sets spdlog's level to config.log_level.
  /// Throws InputError for an unknown log level, an unreadable mesh,
  /// skeleton or filter file, a bad ignore rule, or an LCM URL that cannot
  /// be opened. A GPU that cannot be had is logged, not thrown (the CPU
  /// answers).
  explicit Daemon(const ServiceConfig& config);
  /// Stop()s.
  ~Daemon();

  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// A function the loop calls on its own thread at least every 250 ms
  /// (service/ops/operations.h: watchdog and Health beats). Before Start().
  void SetLoopTick(std::function<void()> tick);

  /// Starts the loop thread: it handles LCM messages as they arrive and
  /// publishes a status every status_period_s. Call once.
  void Start();

  /// Blocks until every message published to lcm() before the call has been
  /// handled, every pair it formed answered, and every answer delivered to
  /// lcm()'s subscribers. For tests and tools; call from a thread other than
  /// the loop's (any, one at a time). Works before Start() too (then the
  /// caller's thread handles the messages).
  void WaitUntilIdle();

  /// Stops the loop, stops taking poses, answers and publishes every pending
  /// and in-flight pair, then publishes a last status. Idempotent; any thread
  /// except the loop's.
  void Stop();

  /// The daemon's LCM instance (tests on memq:// publish poses and subscribe
  /// to answers through it; subscribe before Start()).
  lcm::LCM* lcm();
  /// The service (for its counters and status).
  CollisionService* service();
  /// The room's name (config's `room`; Operations sets the Agones label's).
  RoomName* room();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd
