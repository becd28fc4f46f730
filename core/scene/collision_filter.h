#pragma once
// Which (link, object) pairs never count as contact (SPEC section 5).

#include <string>
#include <vector>

#include "core/typed_index.h"

namespace sweptccd {

class Environment;
class Skeleton;

/// A set of ignored (link, object) pairs. Immutable during queries.
class CollisionFilter {
 public:
  CollisionFilter() = default;
  CollisionFilter(int num_links, int num_objects);

  /// Ignores contacts between `link` and `object`; kAllLinks or kAllObjects
  /// (an invalid index) for either means all.
  void Ignore(LinkIndex link, ObjectIndex object);
  /// Precondition: both indices valid and in range.
  bool Ignores(LinkIndex link, ObjectIndex object) const {
    return !ignored_.empty() &&
           ignored_[static_cast<size_t>(link.value()) * num_objects_ + object.value()];
  }
  /// Whether `link` ignores every object (then it is never tested).
  bool IgnoresAll(LinkIndex link) const;

  /// Parses `{"ignore": [{"link": "foot_l", "object": 0}, {"link": "*", "object": "floor.obj"}]}`.
  /// Links as ResolveLinkKey reads them (a name first, then "*" = all, then
  /// an index; a JSON number is an index), objects by index, name (path) or "*".
  /// Throws InputError naming `source` and the entry.
  static CollisionFilter FromJson(const std::string& text, const std::string& source,
                                  const Skeleton& skeleton, const Environment& env);
  static CollisionFilter FromFile(const std::string& path, const Skeleton& skeleton,
                                  const Environment& env);
  /// Adds one `LINK:OBJECT` rule (as on the command line). Throws InputError.
  void AddRule(const std::string& rule, const Skeleton& skeleton, const Environment& env);

 private:
  int num_links_ = 0;
  int num_objects_ = 0;
  std::vector<bool> ignored_;
};

}  // namespace sweptccd
