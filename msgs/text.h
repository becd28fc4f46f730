#pragma once
// Text from the wire: the client id rule and escaping for display.

#include <string>
#include <string_view>

namespace sweptccd {

/// Longest client id (SPEC section 8).
inline constexpr size_t kMaxClientIdLength = 64;

/// True when `id` is 1-64 characters, each from [A-Za-z0-9_.-] (SPEC section
/// 8's id rule). Thread-safe.
bool IsValidClientId(std::string_view id);

/// `text` with printable ASCII (0x20-0x7e) as is, except the backslash, and
/// every other byte written as an escape: \\ for the backslash, \n, \r, \t,
/// and \xNN (two lower-case hex digits) for the rest (ESC, other controls,
/// bytes >= 0x7f). The result is one line of printable ASCII, safe for logs
/// and terminals. At most `max_length` input bytes are shown; a longer text
/// ends with "...(N bytes)". Thread-safe.
std::string EscapeForDisplay(std::string_view text, size_t max_length = 256);

/// A refusal's message for the one line a command prints on standard error:
/// EscapeForDisplay with room for long paths (4096 bytes). Thread-safe.
std::string DisplayError(std::string_view message);

}  // namespace sweptccd
