// The one link-key rule (core/avatar/link_key.h: a name first, then "*",
// then an index) in its three users: the collision filter (JSON and
// `--ignore`), the world file's rules and, through ResolveLinkKey and
// LinkKeyWithoutNames, the daemon's ignore_entities. A skeleton whose links
// are literally named "*" and "3" tells the orders apart: before the one
// rule, "*" meant every link in the filter and the world file but the link
// named "*" in the daemon.
#include "core/avatar/link_key.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/world/world_file.h"
#include "tests/common/temp_dir_test.h"

namespace sweptccd {
namespace {

// Links 0 "root", 1 "3", 2 "*", 3 "hand", 4 "foot": the link named "3" is
// not link 3, and the link named "*" is one link.
constexpr char kSkeletonJson[] = R"({"name": "odd", "links": [
  {"name": "root", "parent": null, "a": [0, 0, 0], "b": [0, 0.1, 0], "radius": 0.05},
  {"name": "3", "parent": "root", "a": [0, 0, 0], "b": [0, 0.1, 0], "radius": 0.05},
  {"name": "*", "parent": "3", "a": [0, 0, 0], "b": [0, 0.1, 0], "radius": 0.05},
  {"name": "hand", "parent": "*", "a": [0, 0, 0], "b": [0, 0.1, 0], "radius": 0.05},
  {"name": "foot", "parent": "root", "a": [0, 0, 0], "b": [0, 0.1, 0], "radius": 0.05}]})";

Skeleton OddSkeleton() { return ParseSkeletonJson(kSkeletonJson, "odd.json"); }

TEST(LinkKeyTest, ANameFirstThenStarThenAnIndex) {
  const Skeleton s = OddSkeleton();
  EXPECT_EQ(ResolveLinkKey("*", s, "t"), LinkIndex(2));  // The link named "*".
  EXPECT_EQ(ResolveLinkKey("3", s, "t"), LinkIndex(1));  // The link named "3".
  EXPECT_EQ(ResolveLinkKey("hand", s, "t"), LinkIndex(3));
  EXPECT_EQ(ResolveLinkKey("4", s, "t"), LinkIndex(4));  // No link named "4": index 4.
  EXPECT_EQ(ResolveLinkKey("0", s, "t"), LinkIndex(0));
  EXPECT_THROW(ResolveLinkKey("5", s, "t"), InputError);  // Past the last link.
  EXPECT_THROW(ResolveLinkKey("elbow", s, "t"), InputError);
  EXPECT_THROW(ResolveLinkKey("", s, "t"), InputError);
  EXPECT_THROW(ResolveLinkKey("-1", s, "t"), InputError);
  EXPECT_EQ(ResolveLinkIndex(3, s, "t"), LinkIndex(3));  // A JSON number is an index.
  EXPECT_THROW(ResolveLinkIndex(5, s, "t"), InputError);
  EXPECT_THROW(ResolveLinkIndex(-1, s, "t"), InputError);
  try {
    ResolveLinkKey("elbow", s, "where");
    ADD_FAILURE() << "no refusal";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "where: unknown link 'elbow' in skeleton 'odd' (5 links; give a link name, an "
              "index below 5 or \"*\")");
  }
  // Without a skeleton (a live client to come) only "*" and indices.
  // Without names, "*" is every link.
  EXPECT_EQ(LinkKeyWithoutNames("*"), kAllLinks);
  EXPECT_EQ(LinkKeyWithoutNames("3"), LinkIndex(3));
  EXPECT_FALSE(LinkKeyWithoutNames("hand"));
  EXPECT_FALSE(LinkKeyWithoutNames("1234567890"));  // Over 9 digits.
  // On a skeleton with no link named "*", "*" is every link.
  const Skeleton plain = Skeleton::FromLinks(
      "plain", {Link{"a", -1, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0), 0.1}}, "t");
  EXPECT_EQ(ResolveLinkKey("*", plain, "t"), kAllLinks);
}

Environment TwoObjects() {
  TriangleMesh tri;
  tri.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.indices = {0, 1, 2};
  Environment env;
  env.AddMesh(tri, "floor.obj");
  env.AddMesh(tri, "table.obj");
  return env;
}

// Which links a filter ignores against object 0.
std::vector<int> IgnoredLinks(const CollisionFilter& f, int num_links) {
  std::vector<int> out;
  for (LinkIndex l(0); l < num_links; ++l) {
    if (f.Ignores(l, ObjectIndex(0))) out.push_back(l.value());
  }
  return out;
}

TEST(LinkKeyTest, TheCollisionFilterReadsLinksByTheOneRule) {
  const Skeleton s = OddSkeleton();
  const Environment env = TwoObjects();
  using V = std::vector<int>;
  auto from_json = [&](const std::string& link) {
    return IgnoredLinks(
        CollisionFilter::FromJson(R"({"ignore": [{"link": )" + link + R"(, "object": 0}]})",
                                  "f.json", s, env),
        s.num_links());
  };
  EXPECT_EQ(from_json(R"("*")"), V({2}));
  EXPECT_EQ(from_json(R"("3")"), V({1}));
  EXPECT_EQ(from_json("3"), V({3}));  // A JSON number: the index.
  EXPECT_EQ(from_json(R"("4")"), V({4}));
  EXPECT_THROW(from_json("5"), InputError);
  auto from_rule = [&](const std::string& rule) {
    CollisionFilter f;
    f.AddRule(rule, s, env);
    return IgnoredLinks(f, s.num_links());
  };
  EXPECT_EQ(from_rule("*:0"), V({2}));
  EXPECT_EQ(from_rule("3:floor.obj"), V({1}));
  EXPECT_EQ(from_rule("foot:*"), V({4}));
  const Skeleton plain =
      Skeleton::FromLinks("plain",
                          {Link{"a", -1, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0), 0.1},
                           Link{"b", 0, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0), 0.1}},
                          "t");
  CollisionFilter all;
  all.AddRule("*:0", plain, env);
  EXPECT_EQ(IgnoredLinks(all, 2), V({0, 1}));  // No link named "*": every link.
}

class LinkKeyWorldTest : public test::TempDirTest {
 protected:
  LinkKeyWorldTest() : TempDirTest("link_key") {}
};

TEST_F(LinkKeyWorldTest, TheWorldFileReadsLinksByTheOneRule) {
  Write("odd.json", kSkeletonJson);
  Write("a.jsonl", "");
  Write("b.jsonl", "");
  const std::string world = Write("world.json", R"({"avatars": [
    {"id": "a", "skeleton": "odd.json", "poses": "a.jsonl", "ignore": [
      {"link": "*", "entity": "b"},
      {"link": "3", "entity": "b", "other_link": "*"},
      {"link": 3, "entity": "b", "other_link": "3"},
      {"link": "4", "entity": "b", "other_link": 0}]},
    {"id": "b", "skeleton": "odd.json", "poses": "b.jsonl"}]})");
  const world::LoadedWorld w = world::LoadWorldFile(world);
  ASSERT_EQ(w.world.rules.size(), 2u);
  const auto& rules = w.world.rules[0];
  ASSERT_EQ(rules.size(), 4u);
  EXPECT_EQ(rules[0].link, 2);        // The link named "*", not every link.
  EXPECT_EQ(rules[1].link, 1);        // The link named "3",
  EXPECT_EQ(rules[1].other_link, 2);  // and b's link named "*".
  EXPECT_EQ(rules[2].link, 3);        // A JSON number: the index,
  EXPECT_EQ(rules[2].other_link, 1);  // and b's link named "3".
  EXPECT_EQ(rules[3].link, 4);        // No link named "4": index 4.
  EXPECT_EQ(rules[3].other_link, 0);
}

}  // namespace
}  // namespace sweptccd
