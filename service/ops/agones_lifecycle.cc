#include "service/ops/agones_lifecycle.h"

#include <spdlog/spdlog.h>

#include "msgs/text.h"
#include "service/ops/gameserver_room.h"

namespace sweptccd {

using Clock = std::chrono::steady_clock;

AgonesLifecycle::AgonesLifecycle(AgonesSdk sdk, AgonesOptions options,
                                 std::function<int()> live_clients, RoomName* room)
    : sdk_(std::move(sdk)),
      options_(options),
      live_clients_(std::move(live_clients)),
      room_(room) {}

AgonesLifecycle::~AgonesLifecycle() { Stop(); }

namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

}  // namespace

void AgonesLifecycle::Beat() { last_beat_ns_.store(NowNs(), std::memory_order_relaxed); }

void AgonesLifecycle::Start() {
  thread_ = std::thread([this] { Run(); });
}

void AgonesLifecycle::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  stop_flag_.store(true);
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (watch_thread_.joinable()) watch_thread_.join();
}

bool AgonesLifecycle::SleepFor(std::chrono::duration<double> d) {
  std::unique_lock<std::mutex> lock(mutex_);
  return !cv_.wait_for(lock, d, [this] { return stopping_; });
}

void AgonesLifecycle::Run() {
  // Ready: the sidecar may come up after the daemon; retried every 0.5 s.
  for (int attempt = 1; !sdk_.Ready(); ++attempt) {
    if (attempt == 1) spdlog::warn("agones: Ready not accepted yet; retrying every 0.5 s");
    if (!SleepFor(std::chrono::milliseconds(500))) return;
  }
  spdlog::info("agones: Ready");
  watch_thread_ = std::thread([this] { WatchRoom(); });
  const auto period = std::chrono::duration<double>(options_.health_period_s);
  bool wedged_logged = false, shutdown_sent = false;
  // When the room was first seen empty (sampled every period, so the room
  // has been empty at least since then): Ready with no one in it yet.
  bool empty = true;
  Clock::time_point empty_since = Clock::now();
  while (SleepFor(period)) {
    const int64_t silent_ns = NowNs() - last_beat_ns_.load(std::memory_order_relaxed);
    if (silent_ns < std::chrono::nanoseconds(kStallLimit).count()) {
      sdk_.Health();
      wedged_logged = false;
    } else if (!wedged_logged) {
      spdlog::error("agones: the daemon's loop has not run for {:.1f} s; Health pings stop",
                    static_cast<double>(silent_ns) * 1e-9);
      wedged_logged = true;
    }
    const auto now = Clock::now();
    if (live_clients_() > 0) {
      empty = false;
    } else if (!empty) {
      empty = true;
      empty_since = now;
    }
    if (!shutdown_sent && options_.empty_shutdown_s > 0 && empty &&
        now - empty_since >= std::chrono::duration<double>(options_.empty_shutdown_s)) {
      spdlog::info("agones: the room has been empty for {} s (agones.empty_shutdown_s): Shutdown",
                   options_.empty_shutdown_s);
      shutdown_sent = sdk_.Shutdown();
    }
  }
}

void AgonesLifecycle::ApplyGameServer(const std::string& json, bool watch_event) {
  const GameServerRoom r = RoomOfGameServer(json, watch_event);
  if (!r.problem.empty()) {
    if (r.problem != last_problem_) {
      spdlog::warn("agones: the GameServer's room: {}; the room stays '{}'", r.problem,
                   EscapeForDisplay(room_->Get()));
    }
    last_problem_ = r.problem;
    return;
  }
  last_problem_.clear();
  if (!r.room.empty() && room_->Set(r.room)) {
    spdlog::info("agones: this server holds room '{}' (GameServer label {})", r.room, kRoomLabel);
  }
}

void AgonesLifecycle::WatchRoom() {
  int failures = 0;
  while (!stop_flag_.load()) {
    std::string error;
    const bool stopped =
        sdk_.WatchGameServer([this](const std::string& line) { ApplyGameServer(line, true); },
                             [this, &failures] {
                               failures = 0;
                               // What changed before the stream opened is not streamed.
                               const std::string gs = sdk_.GetGameServer();
                               if (!gs.empty()) ApplyGameServer(gs, false);
                             },
                             [this] { return stop_flag_.load(); }, &error);
    if (stopped) return;
    // Once per streak of failures (a sidecar that is not up yet fails each second).
    if (++failures == 1)
      spdlog::warn("agones: {}; the GameServer watch reconnects every 1 s", error);
    if (!SleepFor(std::chrono::seconds(1))) return;
  }
}

}  // namespace sweptccd
