#include "service/ws/static_files.h"

#include <sys/stat.h>

#include <climits>
#include <cstdlib>

namespace sweptccd::ws {

namespace {

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

std::optional<std::string> RealPath(const std::string& path) {
  char buf[PATH_MAX];
  if (realpath(path.c_str(), buf) == nullptr) return std::nullopt;
  return std::string(buf);
}

}  // namespace

std::optional<std::string> ResolveViewFile(const std::string& view_dir, std::string_view target) {
  if (view_dir.empty() || target.empty() || target.front() != '/') return std::nullopt;
  target = target.substr(0, target.find('?'));
  if (target.size() > 512) return std::nullopt;
  std::string_view rel = target.substr(1);
  if (rel.substr(0, 5) == "view/") rel = rel.substr(5);
  if (rel.empty() || rel == "view") rel = "index.html";
  // Segments of [A-Za-z0-9_.-], none empty or starting with '.'.
  size_t start = 0;
  while (start <= rel.size()) {
    const size_t end = std::min(rel.find('/', start), rel.size());
    const std::string_view seg = rel.substr(start, end - start);
    if (seg.empty() || seg.front() == '.') return std::nullopt;
    for (const char c : seg) {
      const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '.' || c == '-';
      if (!ok) return std::nullopt;
    }
    start = end + 1;
  }
  const std::optional<std::string> root = RealPath(view_dir);
  if (!root) return std::nullopt;
  const std::optional<std::string> file = RealPath(*root + "/" + std::string(rel));
  if (!file || file->compare(0, root->size() + 1, *root + "/") != 0) return std::nullopt;
  struct stat st {};
  if (stat(file->c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return file;
}

const char* ContentTypeOf(std::string_view path) {
  if (EndsWith(path, ".html")) return "text/html; charset=utf-8";
  if (EndsWith(path, ".js") || EndsWith(path, ".mjs")) return "text/javascript; charset=utf-8";
  if (EndsWith(path, ".css")) return "text/css; charset=utf-8";
  if (EndsWith(path, ".json") || EndsWith(path, ".map")) return "application/json";
  if (EndsWith(path, ".wasm")) return "application/wasm";
  if (EndsWith(path, ".png")) return "image/png";
  if (EndsWith(path, ".svg")) return "image/svg+xml";
  return "application/octet-stream";
}

}  // namespace sweptccd::ws
