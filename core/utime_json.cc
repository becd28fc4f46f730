#include "core/utime_json.h"

#include <cmath>
#include <cstdint>

namespace sweptccd {

bool ReadUtime(const nlohmann::json& j, int64_t* utime) {
  if (j.is_number_unsigned()) {
    if (j.get<uint64_t>() > static_cast<uint64_t>(INT64_MAX)) return false;
    *utime = static_cast<int64_t>(j.get<uint64_t>());
    return true;
  }
  if (j.is_number_integer()) {
    *utime = j.get<int64_t>();
    return true;
  }
  if (j.is_number_float()) {
    // Accept 1000000.0: integral values within the int64 range, which for a
    // double is [-2^63, 2^63) exactly.
    const double v = j.get<double>();
    if (!std::isfinite(v) || v != std::floor(v) || v < -0x1p63 || v >= 0x1p63) return false;
    *utime = static_cast<int64_t>(v);
    return true;
  }
  return false;
}

}  // namespace sweptccd
