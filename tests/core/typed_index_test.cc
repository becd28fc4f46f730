// Typed indices (core/typed_index.h): what must not compile, and the
// collision filter's wildcards through them.

#include "core/typed_index.h"

#include <gtest/gtest.h>

#include <sstream>
#include <type_traits>

#include "core/scene/collision_filter.h"

namespace sweptccd {
namespace {

// A bare int never becomes an index implicitly, and one kind never becomes
// the other, so a swapped (link, object) pair does not compile.
static_assert(!std::is_convertible_v<int, LinkIndex>);
static_assert(!std::is_convertible_v<ObjectIndex, LinkIndex>);
static_assert(!std::is_constructible_v<LinkIndex, ObjectIndex>);
static_assert(!std::is_constructible_v<ObjectIndex, LinkIndex>);
static_assert(std::is_convertible_v<LinkIndex, int>);  // Indexing arrays.

template <class A, class B, class = void>
struct Comparable : std::false_type {};
template <class A, class B>
struct Comparable<A, B, std::void_t<decltype(std::declval<A>() == std::declval<B>())>>
    : std::true_type {};
static_assert(Comparable<LinkIndex, LinkIndex>::value);
static_assert(!Comparable<LinkIndex, ObjectIndex>::value);

template <class L, class O>
using IgnoresCall = decltype(std::declval<CollisionFilter>().Ignores(std::declval<L>(),
                                                                     std::declval<O>()));
template <class L, class O, class = void>
struct IgnoresAccepts : std::false_type {};
template <class L, class O>
struct IgnoresAccepts<L, O, std::void_t<IgnoresCall<L, O>>> : std::true_type {};
static_assert(IgnoresAccepts<LinkIndex, ObjectIndex>::value);
static_assert(!IgnoresAccepts<ObjectIndex, LinkIndex>::value);
static_assert(!IgnoresAccepts<int, int>::value);

TEST(TypedIndexTest, DefaultIsInvalidAndPrintsItsValue) {
  EXPECT_FALSE(LinkIndex().is_valid());
  EXPECT_EQ(LinkIndex().value(), -1);
  EXPECT_TRUE(LinkIndex(0).is_valid());
  std::ostringstream out;
  out << ObjectIndex(7);
  EXPECT_EQ(out.str(), "7");
  LinkIndex l(3);
  ++l;
  EXPECT_EQ(l, LinkIndex(4));
}

TEST(TypedIndexTest, FilterWildcards) {
  CollisionFilter filter(3, 4);
  filter.Ignore(LinkIndex(0), kAllObjects);
  filter.Ignore(kAllLinks, ObjectIndex(2));
  filter.Ignore(LinkIndex(1), ObjectIndex(3));
  for (LinkIndex l(0); l < 3; ++l) {
    for (ObjectIndex o(0); o < 4; ++o) {
      const bool expected = l == LinkIndex(0) || o == ObjectIndex(2) ||
                            (l == LinkIndex(1) && o == ObjectIndex(3));
      EXPECT_EQ(filter.Ignores(l, o), expected) << "link " << l << " object " << o;
    }
  }
  EXPECT_TRUE(filter.IgnoresAll(LinkIndex(0)));
  EXPECT_FALSE(filter.IgnoresAll(LinkIndex(1)));
  EXPECT_FALSE(CollisionFilter().IgnoresAll(LinkIndex(2)));
}

}  // namespace
}  // namespace sweptccd
