#pragma once
// A check every JSON input runs before nlohmann::json parses it.

#include <string>

namespace sweptccd {

/// nlohmann::json (3.11) ends its input at the first NUL byte and accepts the
/// JSON before it: "{...}\0garbage" parses as "{...}". JSON text never holds
/// a raw NUL, so text with one is malformed. Returns "" when `text` has none,
/// else "a NUL byte at offset N" for the message that refuses it.
std::string NulByteProblem(const std::string& text);

}  // namespace sweptccd
