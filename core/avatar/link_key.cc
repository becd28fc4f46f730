#include "core/avatar/link_key.h"

#include "core/avatar/skeleton.h"
#include "core/errors.h"

namespace sweptccd {

namespace {

// 1-9 decimal digits as an index, else nullopt.
std::optional<int> DecimalIndex(const std::string& key) {
  if (key.empty() || key.size() > 9 || key.find_first_not_of("0123456789") != std::string::npos) {
    return std::nullopt;
  }
  return std::stoi(key);
}

}  // namespace

LinkIndex ResolveLinkKey(const std::string& key, const Skeleton& skeleton,
                         const std::string& where) {
  const int found = skeleton.FindLink(key);
  if (found >= 0) return LinkIndex(found);
  if (key == "*") return kAllLinks;
  const std::optional<int> index = DecimalIndex(key);
  if (index && *index < skeleton.num_links()) return LinkIndex(*index);
  const std::string n = std::to_string(skeleton.num_links());
  throw InputError(where + ": unknown link '" + key + "' in skeleton '" + skeleton.name() + "' (" +
                   n + " links; give a link name, an index below " + n + " or \"*\")");
}

LinkIndex ResolveLinkIndex(int64_t index, const Skeleton& skeleton, const std::string& where) {
  if (index >= 0 && index < skeleton.num_links()) return LinkIndex(static_cast<int>(index));
  throw InputError(where + ": link index " + std::to_string(index) +
                   " is out of range (skeleton '" + skeleton.name() + "' has " +
                   std::to_string(skeleton.num_links()) + " links)");
}

std::optional<LinkIndex> LinkKeyWithoutNames(const std::string& key) {
  if (key == "*") return kAllLinks;
  if (const std::optional<int> index = DecimalIndex(key)) return LinkIndex(*index);
  return std::nullopt;
}

}  // namespace sweptccd
