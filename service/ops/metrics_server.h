#pragma once
// The Prometheus endpoint on its own loopback port (--metrics-listen,
// metrics.listen): GET /metrics answers the text a callback renders; every
// other path is 404, every other method 405. Plain HTTP on loopback only
// (ValidateOpsOptions): in a pod a scraper reaches it through the pod's
// loopback (a sidecar) or the door's TLS port later (docs/DEPLOY.md).
// One thread, one connection at a time, a 2 s budget per request, an 8 KiB
// request head at most: a scrape is small and rare.

#include <functional>
#include <memory>
#include <string>

namespace sweptccd {

class MetricsServer {
 public:
  /// Binds `listen` (HOST:PORT; port 0 picks one). Throws InputError when it
  /// cannot. Serves nothing until Start().
  MetricsServer(const std::string& listen, std::function<std::string()> render);
  ~MetricsServer();  // Stop()s.
  MetricsServer(const MetricsServer&) = delete;
  MetricsServer& operator=(const MetricsServer&) = delete;

  void Start();
  void Stop();  // Idempotent.
  /// The bound port (the chosen one when `listen` said 0).
  int port() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd
