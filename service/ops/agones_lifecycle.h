#pragma once
// The daemon's life as an Agones GameServer (docs/DEPLOY.md "A fleet on
// Agones"), on a thread of its own so the daemon's loop never waits on HTTP:
// Ready (retried until the sidecar answers: it may start after the daemon),
// then every health_period_s a Health ping if the daemon's loop has ticked
// within the last kStallLimit (a wedged loop stops the pings, and Agones
// marks the GameServer Unhealthy), and Shutdown once the room has had no live client
// for empty_shutdown_s. After Ready a second thread follows the GameServer
// (GET /gameserver once the stream GET /watch/gameserver is open, then the
// stream, reconnected every second when it ends) and sets `room` from its
// sweptccd.dev/room label (gameserver_room.h).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>

#include "service/ops/agones_sdk.h"
#include "service/ops/ops_options.h"
#include "service/ops/room_name.h"

namespace sweptccd {

class AgonesLifecycle {
 public:
  /// `live_clients` is called on the lifecycle thread; `room` is set from
  /// the GameServer's label (it must outlive this).
  AgonesLifecycle(AgonesSdk sdk, AgonesOptions options, std::function<int()> live_clients,
                  RoomName* room);
  ~AgonesLifecycle();  // Stop()s.

  /// Starts the thread (after the scene is loaded and the backend calibrated).
  void Start();
  /// A loop that has not ticked for this long is wedged: no more Health.
  /// Four times the loop's tick period (250 ms, Daemon::SetLoopTick).
  static constexpr std::chrono::milliseconds kStallLimit{1000};

  /// Called from the daemon's loop: it is alive.
  void Beat();
  void Stop();

 private:
  void Run();
  void WatchRoom();  // The watch thread.
  void ApplyGameServer(const std::string& json, bool watch_event);
  bool SleepFor(std::chrono::duration<double> d);  // False: stopping.

  AgonesSdk sdk_;
  AgonesOptions options_;
  std::function<int()> live_clients_;
  RoomName* room_;
  std::string last_problem_;  // The last label problem logged (watch thread).
  std::atomic<bool> stop_flag_{false};
  std::atomic<int64_t> last_beat_ns_{0};  // steady_clock, since its epoch.
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::thread thread_;
  std::thread watch_thread_;  // Started by thread_ after Ready.
};

}  // namespace sweptccd
