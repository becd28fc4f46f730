#include "service/ops/agones_sdk.h"

#include <curl/curl.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <memory>

#include "core/errors.h"
#include "msgs/text.h"

namespace sweptccd {

namespace {

constexpr long kTimeoutMs = 1000;
constexpr size_t kMaxAnswerBytes = 1 << 20;

struct Answer {
  std::string body;
  bool too_long = false;
};

size_t Collect(char* data, size_t size, size_t n, void* user) {
  auto* a = static_cast<Answer*>(user);
  if (a->body.size() + size * n > kMaxAnswerBytes) {
    a->too_long = true;
    return 0;  // Aborts the transfer.
  }
  a->body.append(data, size * n);
  return size * n;
}

// One request; true on HTTP 200. `post_body` null: GET.
bool CurlReady() {
  static const bool initialised = curl_global_init(CURL_GLOBAL_DEFAULT) == 0;
  return initialised;
}

bool Request(const std::string& url, const char* post_body, Answer* answer) {
  if (!CurlReady()) return false;
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
  if (!curl) return false;
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, kTimeoutMs);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http");
  curl_easy_setopt(c, CURLOPT_NOPROXY, "*");  // The sidecar is on localhost.
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, Collect);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, answer);
  curl_slist* headers = nullptr;
  if (post_body) {
    headers = curl_slist_append(headers, "Content-Type: application/json");
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, headers);
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, post_body);
  }
  const CURLcode rc = curl_easy_perform(c);
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  curl_slist_free_all(headers);
  if (rc != CURLE_OK) {
    spdlog::warn("agones: {}: {}", url,
                 answer->too_long ? "answer over 1 MiB" : curl_easy_strerror(rc));
    return false;
  }
  if (status != 200) {
    spdlog::warn("agones: {}: HTTP {}: {}", url, status, EscapeForDisplay(answer->body, 200));
    return false;
  }
  return true;
}

// The watch stream: whole lines to on_object, a line over the limit aborts.
struct Stream {
  CURL* curl = nullptr;
  const std::function<void(const std::string&)>* on_object = nullptr;
  std::string line;
  bool too_long = false;
  bool not_ok = false;  // An answer other than 200: its body is not objects.
  std::string error_body;
};

size_t StreamCollect(char* data, size_t size, size_t n, void* user) {
  auto* s = static_cast<Stream*>(user);
  const size_t bytes = size * n;
  long status = 0;
  curl_easy_getinfo(s->curl, CURLINFO_RESPONSE_CODE, &status);
  if (status != 200) {
    s->not_ok = true;
    s->error_body.append(data, std::min<size_t>(bytes, 200));
    return 0;
  }
  size_t begin = 0;
  for (size_t i = 0; i < bytes; ++i) {
    if (data[i] != '\n') continue;
    if (s->line.size() + (i - begin) > AgonesSdk::kMaxWatchObjectBytes) {
      s->too_long = true;
      return 0;
    }
    s->line.append(data + begin, i - begin);
    if (!s->line.empty() && s->line.back() == '\r') s->line.pop_back();
    if (!s->line.empty()) (*s->on_object)(s->line);
    s->line.clear();
    begin = i + 1;
  }
  if (s->line.size() + (bytes - begin) > AgonesSdk::kMaxWatchObjectBytes) {
    s->too_long = true;
    return 0;
  }
  s->line.append(data + begin, bytes - begin);
  return bytes;
}

}  // namespace

std::string AgonesSdk::BaseUrlFromEnvironment() {
  const char* port = std::getenv("AGONES_SDK_HTTP_PORT");
  if (port == nullptr || *port == '\0') {
    throw InputError(
        "--agones: AGONES_SDK_HTTP_PORT is not set (Agones sets it in a GameServer's pod); "
        "run without --agones outside Agones");
  }
  const std::string p(port);
  if (p.size() > 5 || p.find_first_not_of("0123456789") != std::string::npos || std::stoi(p) < 1 ||
      std::stoi(p) > 65535) {
    throw InputError("--agones: AGONES_SDK_HTTP_PORT '" + EscapeForDisplay(p, 20) +
                     "' is not a port number");
  }
  return "http://localhost:" + p;
}

AgonesSdk::AgonesSdk(std::string base_url) : base_url_(std::move(base_url)) {}

bool AgonesSdk::Post(const char* path) {
  Answer answer;
  return Request(base_url_ + path, "{}", &answer);
}

std::string AgonesSdk::GetGameServer() {
  Answer answer;
  return Request(base_url_ + "/gameserver", nullptr, &answer) ? answer.body : std::string();
}

bool AgonesSdk::WatchGameServer(const std::function<void(const std::string&)>& on_object,
                                const std::function<void()>& on_connected,
                                const std::function<bool()>& stop, std::string* error) {
  if (!CurlReady()) return false;
  const std::string url = base_url_ + "/watch/gameserver";
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
  std::unique_ptr<CURLM, decltype(&curl_multi_cleanup)> multi(curl_multi_init(),
                                                              curl_multi_cleanup);
  if (!curl || !multi) return false;
  Stream stream;
  stream.curl = curl.get();
  stream.on_object = &on_object;
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, kTimeoutMs);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http");
  curl_easy_setopt(c, CURLOPT_NOPROXY, "*");
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, StreamCollect);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &stream);
  curl_multi_add_handle(multi.get(), c);
  bool connected = false;
  CURLcode result = CURLE_OK;
  for (;;) {
    int running = 0;
    if (curl_multi_perform(multi.get(), &running) != CURLM_OK) break;
    if (!connected) {
      long status = 0;
      curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
      if (status == 200) {
        connected = true;
        on_connected();
      }
    }
    int queued = 0;
    while (CURLMsg* m = curl_multi_info_read(multi.get(), &queued)) {
      if (m->msg == CURLMSG_DONE) result = m->data.result;
    }
    if (running == 0) break;
    if (stop()) {
      curl_multi_remove_handle(multi.get(), c);
      return true;
    }
    curl_multi_poll(multi.get(), nullptr, 0, 100, nullptr);
  }
  curl_multi_remove_handle(multi.get(), c);
  if (stream.too_long) {
    *error = url + ": a line over " + std::to_string(kMaxWatchObjectBytes) + " bytes";
  } else if (stream.not_ok) {
    long status = 0;
    curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
    *error =
        url + ": HTTP " + std::to_string(status) + ": " + EscapeForDisplay(stream.error_body, 200);
  } else if (result != CURLE_OK) {
    *error = url + ": " + curl_easy_strerror(result);
  } else {
    *error = url + ": the stream ended";
  }
  return false;
}

}  // namespace sweptccd
