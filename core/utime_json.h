#pragma once
// The one utime rule of every line reader: pose lines (SPEC 2) and tracked
// object pose lines (SPEC 8).

#include <cstdint>
#include <nlohmann/json.hpp>

namespace sweptccd {

/// A line's "utime": a JSON integer within int64, or a JSON float with an
/// integral value in the int64 range [-2^63, 2^63) (so 1000000.0 and 1e6 are
/// read as 1000000). Returns false, leaving *utime, for anything else (a
/// fraction, a larger value, a string, ...).
bool ReadUtime(const nlohmann::json& j, int64_t* utime);

}  // namespace sweptccd
