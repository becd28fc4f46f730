#pragma once
// Typed indices (after Drake's TypeSafeIndex): a link index and an object
// index are both small integers, and with bare `int`s a swapped pair compiles
// silently. A TypedIndex is built from an int only explicitly, reads as an
// int implicitly (to index arrays), and cannot be compared with, or passed
// as, an index of another kind.

#include <ostream>
#include <type_traits>

namespace sweptccd {

template <class Tag>
class TypedIndex {
 public:
  /// The invalid index (-1).
  constexpr TypedIndex() = default;
  constexpr explicit TypedIndex(int value) : value_(value) {}
  /// An index of another kind is no index of this kind, even explicitly.
  template <class Other, std::enable_if_t<!std::is_same_v<Other, Tag>, int> = 0>
  TypedIndex(TypedIndex<Other>) = delete;

  constexpr int value() const { return value_; }
  constexpr operator int() const { return value_; }  // NOLINT: indexing arrays.
  constexpr bool is_valid() const { return value_ >= 0; }

  TypedIndex& operator++() {
    ++value_;
    return *this;
  }

 private:
  int value_ = -1;
};

// Comparing indices of two different kinds is a bug: refuse to compile it.
template <class A, class B, std::enable_if_t<!std::is_same_v<A, B>, int> = 0>
bool operator==(TypedIndex<A>, TypedIndex<B>) = delete;
template <class A, class B, std::enable_if_t<!std::is_same_v<A, B>, int> = 0>
bool operator!=(TypedIndex<A>, TypedIndex<B>) = delete;

template <class Tag>
std::ostream& operator<<(std::ostream& out, TypedIndex<Tag> index) {
  return out << index.value();
}

struct LinkTag;
struct ObjectTag;
/// A link of a skeleton, in file order (0-based).
using LinkIndex = TypedIndex<LinkTag>;
/// An object of an environment (one per mesh file, 0-based).
using ObjectIndex = TypedIndex<ObjectTag>;

/// Wildcards for CollisionFilter::Ignore: every link, every object.
inline constexpr LinkIndex kAllLinks{};
inline constexpr ObjectIndex kAllObjects{};

}  // namespace sweptccd
