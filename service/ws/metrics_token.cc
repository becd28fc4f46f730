#include "service/ws/metrics_token.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "core/errors.h"
#include "msgs/text.h"

namespace sweptccd::ws {

namespace {

constexpr size_t kMinToken = 32, kMaxToken = 256;

std::string Problem(const std::string& path, const std::string& what) {
  return "websocket.metrics_token_file '" + EscapeForDisplay(path) + "': " + what;
}

}  // namespace

std::string LoadMetricsToken(const std::string& path) {
  // O_NONBLOCK: a FIFO in its place must not block; it is then refused.
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0)
    throw InputError(Problem(path, std::string("cannot open (") + std::strerror(errno) + ")"));
  std::string text;
  struct stat st {};
  const bool stat_ok = fstat(fd, &st) == 0;
  if (stat_ok && S_ISREG(st.st_mode) && (st.st_mode & 077) == 0) {
    char buf[kMaxToken + 4];
    const ssize_t n = read(fd, buf, sizeof(buf));
    if (n > 0) text.assign(buf, static_cast<size_t>(n));
  }
  close(fd);
  if (!stat_ok || !S_ISREG(st.st_mode)) throw InputError(Problem(path, "not a regular file"));
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof(mode), "%03o", static_cast<unsigned>(st.st_mode & 0777));
    throw InputError(Problem(path, std::string("mode ") + mode +
                                       ", readable or writable by others; run `chmod 600 " +
                                       EscapeForDisplay(path) + "`"));
  }
  if (!text.empty() && text.back() == '\n') text.pop_back();
  if (!text.empty() && text.back() == '\r') text.pop_back();
  bool visible = true;
  for (const char c : text) visible = visible && c > ' ' && c < 0x7f;
  if (text.size() < kMinToken || text.size() > kMaxToken || !visible) {
    throw InputError(Problem(path,
                             "give one line of 32-256 visible ASCII characters (no spaces), "
                             "e.g. `openssl rand -hex 32`"));
  }
  return text;
}

}  // namespace sweptccd::ws
