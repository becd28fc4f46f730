#pragma once
// The live view's static files (docs/WEBSOCKET.md section 1): a request
// target mapped to a regular file inside the view folder, or nothing. No
// listing, no "..", no hidden names, no escapes, no link leading out.

#include <optional>
#include <string>
#include <string_view>

namespace sweptccd::ws {

/// The file `target` (the HTTP request target, query string ignored) names
/// under `view_dir`: "/" is index.html; "/view/X" and "/X" are X. Each path
/// segment must be of [A-Za-z0-9_.-], not start with '.', and the resolved
/// real path must be a regular file inside view_dir's real path. nullopt
/// otherwise. Thread-safe.
std::optional<std::string> ResolveViewFile(const std::string& view_dir, std::string_view target);

/// The Content-Type of a file by its extension (application/octet-stream
/// when unknown).
const char* ContentTypeOf(std::string_view path);

}  // namespace sweptccd::ws
