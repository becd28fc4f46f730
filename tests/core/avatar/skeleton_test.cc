// Tests for core/skeleton.h: the SPEC section 1 example, any link order, and
// every refusal (each message must name the source, the link and the problem).

#include "core/avatar/skeleton.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/bounded_file.h"
#include "core/errors.h"

namespace sweptccd {
namespace {

constexpr char kSource[] = "tests/skel_under_test.json";

constexpr char kSpecExample[] = R"({
  "name": "example",
  "links": [
    {"name": "pelvis", "parent": null,     "a": [0, 0, 0], "b": [0, 0.20, 0], "radius": 0.12},
    {"name": "spine",  "parent": "pelvis", "a": [0, 0, 0], "b": [0, 0.30, 0], "radius": 0.10}
  ]
})";

// One link entry of a skeleton document; `parent` is written verbatim
// (`null` or a quoted name), and so is every other field.
struct Entry {
  std::string name = "\"x\"";
  std::string parent = "null";
  std::string a = "[0, 0, 0]";
  std::string b = "[0, 0.2, 0]";
  std::string radius = "0.1";
  bool omit_name = false, omit_parent = false, omit_a = false, omit_b = false, omit_radius = false;
};

Entry Named(const std::string& name, const std::string& parent) {
  Entry e;
  e.name = "\"" + name + "\"";
  e.parent = parent == "null" ? "null" : "\"" + parent + "\"";
  return e;
}

std::string Doc(const std::vector<Entry>& entries) {
  std::ostringstream s;
  s << "{\"name\": \"t\", \"links\": [";
  for (size_t i = 0; i < entries.size(); ++i) {
    const Entry& e = entries[i];
    std::vector<std::string> fields;
    if (!e.omit_name) fields.push_back("\"name\": " + e.name);
    if (!e.omit_parent) fields.push_back("\"parent\": " + e.parent);
    if (!e.omit_a) fields.push_back("\"a\": " + e.a);
    if (!e.omit_b) fields.push_back("\"b\": " + e.b);
    if (!e.omit_radius) fields.push_back("\"radius\": " + e.radius);
    s << (i ? ", " : "") << "{";
    for (size_t k = 0; k < fields.size(); ++k) s << (k ? ", " : "") << fields[k];
    s << "}";
  }
  s << "]}";
  return s.str();
}

// The message of the InputError that parsing `text` throws ("" if none).
std::string RefusalOf(const std::string& text) {
  try {
    ParseSkeletonJson(text, kSource);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string RefusalOfLinks(std::vector<Link> links) {
  try {
    Skeleton::FromLinks("t", std::move(links), kSource);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// The message names the source and contains every one of `parts`.
void ExpectMentions(const std::string& message, std::initializer_list<std::string> parts) {
  ASSERT_FALSE(message.empty()) << "not refused";
  EXPECT_NE(message.find(kSource), std::string::npos) << "no source in: " << message;
  for (const std::string& p : parts) {
    EXPECT_NE(message.find(p), std::string::npos) << "no '" << p << "' in: " << message;
  }
}

// The message mentions at least one of `parts`.
void ExpectMentionsOneOf(const std::string& message, std::initializer_list<std::string> parts) {
  bool any = false;
  for (const std::string& p : parts) any = any || message.find(p) != std::string::npos;
  std::string all;
  for (const std::string& p : parts) all += " '" + p + "'";
  EXPECT_TRUE(any) << "none of" << all << " in: " << message;
}

TEST(SkeletonTest, ValidJsonFollowedByANulByteIsRefused) {
  // nlohmann::json would stop at the NUL and accept the skeleton before it.
  ASSERT_EQ(RefusalOf(kSpecExample), "");
  ExpectMentions(RefusalOf(std::string(kSpecExample) + std::string("\0{}", 3)),
                 {"not valid JSON", "NUL byte"});
}

TEST(SkeletonTest, SpecExampleParses) {
  const Skeleton s = ParseSkeletonJson(kSpecExample, kSource);
  EXPECT_EQ(s.name(), "example");
  ASSERT_EQ(s.num_links(), 2);
  EXPECT_EQ(s.root(), 0);
  EXPECT_EQ(s.link(0).name, "pelvis");
  EXPECT_EQ(s.link(0).parent, -1);
  EXPECT_EQ(s.link(1).name, "spine");
  EXPECT_EQ(s.link(1).parent, 0);
  EXPECT_EQ(s.link(0).b_L, Eigen::Vector3d(0, 0.20, 0));
  EXPECT_EQ(s.link(1).b_L, Eigen::Vector3d(0, 0.30, 0));
  EXPECT_EQ(s.link(0).a_L, Eigen::Vector3d::Zero());
  EXPECT_EQ(s.link(0).radius, 0.12);
  EXPECT_EQ(s.link(1).radius, 0.10);
  EXPECT_EQ(s.topological_order(), (std::vector<int>{0, 1}));
  EXPECT_EQ(s.FindLink("spine"), 1);
  EXPECT_EQ(s.FindLink("pelvis"), 0);
  EXPECT_EQ(s.FindLink("head"), -1);
}

TEST(SkeletonTest, ChildBeforeParentIsAccepted) {
  const Skeleton s = ParseSkeletonJson(
      Doc({Named("hand", "forearm"), Named("forearm", "upper"), Named("upper", "null")}), kSource);
  ASSERT_EQ(s.num_links(), 3);
  EXPECT_EQ(s.root(), 2);
  EXPECT_EQ(s.link(0).parent, 1);
  EXPECT_EQ(s.link(1).parent, 2);
  EXPECT_EQ(s.topological_order(), (std::vector<int>{2, 1, 0}));
  EXPECT_EQ(s.depth_first_order(), (std::vector<int>{2, 1, 0}));
}

// Random trees of 1-30 links written in a random order: each parses, keeps the
// file's indices, the topological order puts every parent first, and the
// depth-first order keeps every subtree together.
TEST(SkeletonTest, RandomTreesInAnyOrderAreAccepted) {
  std::mt19937_64 g(0x5ce1e701);
  for (int c = 0; c < 2000; ++c) {
    const int n = std::uniform_int_distribution<int>(1, 30)(g);
    std::vector<int> parent(n, -1);
    for (int i = 1; i < n; ++i) parent[i] = std::uniform_int_distribution<int>(0, i - 1)(g);
    std::vector<int> perm(n);  // File position of the i-th created link.
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), g);
    std::vector<Entry> entries(n);
    for (int i = 0; i < n; ++i) {
      entries[perm[i]] =
          Named("n" + std::to_string(i), parent[i] < 0 ? "null" : "n" + std::to_string(parent[i]));
    }
    const Skeleton s = ParseSkeletonJson(Doc(entries), kSource);
    ASSERT_EQ(s.num_links(), n);
    EXPECT_EQ(s.root(), perm[0]);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(s.link(perm[i]).name, "n" + std::to_string(i));
      EXPECT_EQ(s.link(perm[i]).parent, parent[i] < 0 ? -1 : perm[parent[i]]);
    }
    const std::vector<int>& order = s.topological_order();
    ASSERT_EQ(static_cast<int>(order.size()), n);
    std::vector<int> position(n, -1);
    for (int k = 0; k < n; ++k) position[order[k]] = k;
    for (int i = 0; i < n; ++i) {
      ASSERT_GE(position[i], 0);
      if (s.link(i).parent >= 0) {
        EXPECT_LT(position[s.link(i).parent], position[i]);
      }
    }
    // The depth-first order: a permutation in which every subtree (found by
    // walking each link's ancestors) fills the positions right after its
    // root, and siblings come in index order.
    const std::vector<int>& dfs = s.depth_first_order();
    ASSERT_EQ(static_cast<int>(dfs.size()), n);
    std::vector<int> at(n, -1);
    for (int k = 0; k < n; ++k) {
      ASSERT_EQ(at[dfs[k]], -1);
      at[dfs[k]] = k;
    }
    for (int top = 0; top < n; ++top) {
      int size = 0;
      for (int i = 0; i < n; ++i) {
        int k = i;
        while (k != -1 && k != top) k = s.link(k).parent;
        if (k != top) continue;
        ++size;
      }
      for (int i = 0; i < n; ++i) {
        int k = i;
        while (k != -1 && k != top) k = s.link(k).parent;
        if (k != top) continue;
        EXPECT_GE(at[i], at[top]);
        EXPECT_LT(at[i], at[top] + size);
      }
      for (int i = 0; i < n; ++i) {
        for (int j = i + 1; j < n; ++j) {
          if (s.link(i).parent == top && s.link(j).parent == top) {
            EXPECT_LT(at[i], at[j]);
          }
        }
      }
    }
  }
}

// Each link's extent bounds the distance of its segment's ends from its
// origin from above, by a few ulps at most: the brute force is the larger
// of the two ends' norms, in long double.
TEST(SkeletonTest, ExtentIsTheFartherEndRoundedUp) {
  std::mt19937_64 g(0xe7e47);
  std::uniform_real_distribution<double> u(-2, 2);
  std::vector<Link> links(200);
  for (int i = 0; i < 200; ++i) {
    links[i].name = "l" + std::to_string(i);
    links[i].parent = i - 1;
    links[i].radius = 0.05;
    const double scale = std::pow(10.0, std::uniform_int_distribution<int>(-6, 2)(g));
    links[i].a_L = scale * Eigen::Vector3d(u(g), u(g), u(g));
    links[i].b_L = scale * Eigen::Vector3d(u(g), u(g), u(g));
    if (i % 7 == 0) links[i].b_L.setZero();
  }
  const Skeleton s = Skeleton::FromLinks("random", links, kSource);
  for (int i = 0; i < 200; ++i) {
    auto norm = [](const Eigen::Vector3d& v) {
      const long double x = v.x(), y = v.y(), z = v.z();
      return std::sqrt(x * x + y * y + z * z);
    };
    const long double want = std::max(norm(links[i].a_L), norm(links[i].b_L));
    EXPECT_GE(static_cast<long double>(s.extent(i)), want) << i;
    EXPECT_LE(static_cast<long double>(s.extent(i)), want * (1 + 1e-14L)) << i;
  }
}

TEST(SkeletonTest, SphereLinkIsAccepted) {
  Entry e = Named("ball", "null");
  e.a = e.b = "[0.1, 0.2, 0.3]";
  const Skeleton s = ParseSkeletonJson(Doc({e}), kSource);
  EXPECT_EQ(s.link(0).a_L, s.link(0).b_L);
}

TEST(SkeletonTest, RefusesUnknownParent) {
  const std::string m = RefusalOf(Doc({Named("pelvis", "null"), Named("spine", "pelvsi")}));
  ExpectMentions(m, {"'spine'", "unknown parent", "pelvsi"});
}

TEST(SkeletonTest, RefusesTwoRoots) {
  const std::string m = RefusalOf(Doc({Named("pelvis", "null"), Named("head", "null")}));
  ExpectMentions(m, {"'head'", "root"});
}

TEST(SkeletonTest, RefusesLoopBesideTheRoot) {
  const std::string m = RefusalOf(Doc({Named("root", "null"), Named("a", "c"), Named("b", "a"),
                                       Named("c", "b"), Named("d", "root")}));
  ExpectMentions(m, {"loop"});
  ExpectMentionsOneOf(m, {"'a'", "'b'", "'c'"});
}

TEST(SkeletonTest, RefusesLinkThatIsItsOwnParent) {
  const std::string m = RefusalOf(Doc({Named("root", "null"), Named("self", "self")}));
  ExpectMentions(m, {"'self'", "loop"});
}

// With no root at all every link is on a loop (or hangs from one); the SPEC
// wants the message to name a link, as it does for a loop beside a root.
TEST(SkeletonTest, RefusesLoopWithoutRootNamingALink) {
  const std::string m = RefusalOf(Doc({Named("a", "b"), Named("b", "a")}));
  ExpectMentions(m, {"root"});
  ExpectMentionsOneOf(m, {"'a'", "'b'"});
}

TEST(SkeletonTest, RefusesRadiusZeroOrNegative) {
  for (const char* r : {"0", "0.0", "-0.0", "-0.05", "-1e300", "5e-324"}) {
    Entry bad = Named("thigh", "pelvis");
    bad.radius = r;
    const std::string m = RefusalOf(Doc({Named("pelvis", "null"), bad}));
    if (std::string(r) == "5e-324") {
      EXPECT_EQ(m, "") << "the smallest positive radius is > 0";
      continue;
    }
    ExpectMentions(m, {"'thigh'", "radius"});
  }
}

// JSON has no NaN or infinity; a number that overflows (1e999) is how a file
// holds a non-finite value. It must be refused, naming the source.
TEST(SkeletonTest, RefusesOverflowingJsonNumber) {
  for (const char* field : {"a", "b", "radius"}) {
    Entry bad = Named("shin", "pelvis");
    if (std::string(field) == "a") bad.a = "[0, 1e999, 0]";
    if (std::string(field) == "b") bad.b = "[-1e999, 0, 0]";
    if (std::string(field) == "radius") bad.radius = "1e999";
    const std::string m = RefusalOf(Doc({Named("pelvis", "null"), bad}));
    ExpectMentions(m, {});
    ExpectMentionsOneOf(m, {"1e999", "overflow", "finite"});
  }
}

// The same refusal should name the link like every other bad-number refusal
// (SPEC section 1: "names the link and the problem: ... non-finite numbers").
TEST(SkeletonTest, OverflowingJsonNumberMessageNamesTheLink) {
  Entry bad = Named("shin", "pelvis");
  bad.radius = "1e999";
  const std::string m = RefusalOf(Doc({Named("pelvis", "null"), bad}));
  ExpectMentions(m, {});
  ExpectMentionsOneOf(m, {"'shin'", "link 1"});
}

TEST(SkeletonTest, FromLinksRefusesNonFiniteNumbers) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (int field = 0; field < 3; ++field) {
    for (double bad : {nan, inf, -inf}) {
      std::vector<Link> links(2);
      links[0].name = "pelvis";
      links[0].b_L = Eigen::Vector3d(0, 0.2, 0);
      links[0].radius = 0.1;
      links[1].name = "knee";
      links[1].parent = 0;
      links[1].radius = 0.05;
      if (field == 0) links[1].a_L.y() = bad;
      if (field == 1) links[1].b_L.z() = bad;
      if (field == 2) links[1].radius = bad;
      const std::string m = RefusalOfLinks(links);
      ExpectMentions(m, {"'knee'", "finite"});
    }
  }
}

TEST(SkeletonTest, RefusesDuplicateNames) {
  const std::string m =
      RefusalOf(Doc({Named("pelvis", "null"), Named("arm", "pelvis"), Named("arm", "pelvis")}));
  ExpectMentions(m, {"'arm'", "duplicate"});
}

TEST(SkeletonTest, RefusesMissingFields) {
  struct Case {
    const char* field;
    void (*omit)(Entry*);
  } cases[] = {{"name", [](Entry* e) { e->omit_name = true; }},
               {"parent", [](Entry* e) { e->omit_parent = true; }},
               {"'a'", [](Entry* e) { e->omit_a = true; }},
               {"'b'", [](Entry* e) { e->omit_b = true; }},
               {"radius", [](Entry* e) { e->omit_radius = true; }}};
  for (const Case& c : cases) {
    Entry bad = Named("elbow", "pelvis");
    c.omit(&bad);
    const std::string m = RefusalOf(Doc({Named("pelvis", "null"), bad}));
    // A link without a name can only be named by its index.
    ExpectMentions(m, {std::string(c.field) == "name" ? "link 1" : "'elbow'", c.field});
  }
}

TEST(SkeletonTest, RefusesWrongTypes) {
  struct Case {
    const char* what;
    void (*spoil)(Entry*);
    const char* expect;
  } cases[] = {
      {"name is a number", [](Entry* e) { e->name = "7"; }, "name"},
      {"parent is a number", [](Entry* e) { e->parent = "0"; }, "parent"},
      {"parent is an array", [](Entry* e) { e->parent = "[\"pelvis\"]"; }, "parent"},
      {"a is a string", [](Entry* e) { e->a = "\"0,0,0\""; }, "'a'"},
      {"a has 2 entries", [](Entry* e) { e->a = "[0, 0]"; }, "'a'"},
      {"a has 4 entries", [](Entry* e) { e->a = "[0, 0, 0, 0]"; }, "'a'"},
      {"b holds a string", [](Entry* e) { e->b = "[0, \"1\", 0]"; }, "'b'"},
      {"b holds null", [](Entry* e) { e->b = "[0, null, 0]"; }, "'b'"},
      {"radius is a string", [](Entry* e) { e->radius = "\"0.1\""; }, "radius"},
      {"radius is null", [](Entry* e) { e->radius = "null"; }, "radius"},
      {"radius is an array", [](Entry* e) { e->radius = "[0.1]"; }, "radius"},
  };
  for (const Case& c : cases) {
    Entry bad = Named("wrist", "pelvis");
    c.spoil(&bad);
    const std::string m = RefusalOf(Doc({Named("pelvis", "null"), bad}));
    SCOPED_TRACE(c.what);
    // A link whose name is not a string is named by its index.
    ExpectMentions(m, {std::string(c.expect) == "name" ? "link 1" : "'wrist'", c.expect});
  }
  // The document itself.
  ExpectMentions(RefusalOf("[1, 2, 3]"), {"object"});
  ExpectMentions(RefusalOf(R"({"name": 5, "links": []})"), {"name"});
  ExpectMentions(RefusalOf(R"({"name": "t", "links": {}})"), {"links"});
  ExpectMentions(RefusalOf(R"({"name": "t"})"), {"links"});
  ExpectMentions(RefusalOf(R"({"name": "t", "links": [42]})"), {"link 0", "object"});
}

TEST(SkeletonTest, RefusesNotJson) {
  for (const char* text : {"", "{", "garbage", "{\"links\": [}", "\x01\x02", "{} {}"}) {
    SCOPED_TRACE(text);
    ExpectMentions(RefusalOf(text), {"JSON"});
  }
}

TEST(SkeletonTest, RefusesEmptyLinks) {
  ExpectMentions(RefusalOf(R"({"name": "t", "links": []})"), {"no links"});
  ExpectMentions(RefusalOfLinks({}), {"no links"});
}

TEST(SkeletonTest, FromLinksRefusesBadParentIndicesAndNames) {
  std::vector<Link> links(2);
  links[0].name = "root";
  links[0].radius = 0.1;
  links[1].name = "leaf";
  links[1].radius = 0.1;
  links[1].parent = 7;
  ExpectMentions(RefusalOfLinks(links), {"'leaf'", "parent"});
  links[1].parent = -2;
  ExpectMentions(RefusalOfLinks(links), {"'leaf'", "parent"});
  links[1].parent = 0;
  links[1].name = "";
  ExpectMentions(RefusalOfLinks(links), {"link 1", "name"});
}

// Seeded random skeletons with one defect injected: the refusal names the
// defective link (or, for a loop, a link that never reaches the root).
TEST(SkeletonTest, RandomDefectsAreRefusedNamingTheLink) {
  std::mt19937_64 g(0x5ce1e702);
  int64_t refused = 0;
  for (int c = 0; c < 3000; ++c) {
    const int n = std::uniform_int_distribution<int>(2, 25)(g);
    std::vector<Entry> entries(n);
    std::vector<int> parent(n, -1);
    auto name = [](int i) { return "q" + std::to_string(i) + "z"; };
    for (int i = 0; i < n; ++i) {
      if (i > 0) parent[i] = std::uniform_int_distribution<int>(0, i - 1)(g);
      entries[i] = Named(name(i), parent[i] < 0 ? "null" : name(parent[i]));
    }
    const int victim = std::uniform_int_distribution<int>(1, n - 1)(g);
    const int defect = std::uniform_int_distribution<int>(0, 4)(g);
    std::vector<std::string> named_ok;  // Any of these may be the named link.
    std::string problem;
    switch (defect) {
      case 0:
        entries[victim].parent = "\"nobody\"";
        named_ok = {name(victim)};
        problem = "unknown parent";
        break;
      case 1:
        entries[victim].parent = "null";
        named_ok = {name(victim), name(0)};
        problem = "root";
        break;
      case 2:
        entries[victim].radius = std::uniform_int_distribution<int>(0, 1)(g) ? "0" : "-0.25";
        named_ok = {name(victim)};
        problem = "radius";
        break;
      case 3: {
        // A leaf takes another link's name (not its parent's, which would
        // make it its own parent): nothing refers to the lost name.
        const int other = std::uniform_int_distribution<int>(0, n - 1)(g);
        if (other == victim || other == parent[victim] ||
            std::find(parent.begin(), parent.end(), victim) != parent.end()) {
          continue;
        }
        entries[victim].name = "\"" + name(other) + "\"";
        named_ok = {name(other)};
        problem = "duplicate";
        break;
      }
      default: {
        // Point the victim at one of its descendants (or itself): a loop.
        std::vector<int> below = {victim};
        for (int i = victim + 1; i < n; ++i) {
          if (std::find(below.begin(), below.end(), parent[i]) != below.end()) below.push_back(i);
        }
        const int to = below[std::uniform_int_distribution<size_t>(0, below.size() - 1)(g)];
        entries[victim].parent = "\"" + name(to) + "\"";
        for (int i : below) named_ok.push_back(name(i));
        problem = "loop";
        break;
      }
    }
    std::vector<int> order(n);  // Shuffle the file order too.
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), g);
    std::vector<Entry> shuffled(n);
    for (int i = 0; i < n; ++i) shuffled[order[i]] = entries[i];
    const std::string m = RefusalOf(Doc(shuffled));
    SCOPED_TRACE("case " + std::to_string(c) + " defect " + std::to_string(defect));
    ASSERT_FALSE(m.empty());
    ++refused;
    EXPECT_NE(m.find(kSource), std::string::npos) << m;
    EXPECT_NE(m.find(problem), std::string::npos) << m;
    bool names_one = false;
    for (const std::string& s : named_ok)
      names_one = names_one || m.find("'" + s + "'") != std::string::npos;
    EXPECT_TRUE(names_one) << m;
  }
  EXPECT_GT(refused, 2000);
}

TEST(SkeletonTest, JsonRoundTrip) {
  std::mt19937_64 g(0x5ce1e703);
  std::uniform_real_distribution<double> coord(-2, 2), radius(1e-6, 0.5);
  for (int c = 0; c < 500; ++c) {
    const int n = std::uniform_int_distribution<int>(1, 30)(g);
    std::vector<Link> links(n);
    std::vector<int> perm(n);
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), g);
    for (int i = 0; i < n; ++i) {
      Link& l = links[perm[i]];
      l.name = "link \"" + std::to_string(i) + "\" \xC3\xA9";  // Quotes and UTF-8 survive.
      l.parent = i == 0 ? -1 : perm[std::uniform_int_distribution<int>(0, i - 1)(g)];
      l.a_L = Eigen::Vector3d(coord(g), coord(g), coord(g));
      l.b_L = c % 7 == 0 ? l.a_L : Eigen::Vector3d(coord(g), coord(g), coord(g));
      l.radius = radius(g);
    }
    const Skeleton s = Skeleton::FromLinks("round trip " + std::to_string(c), links, kSource);
    const Skeleton t = ParseSkeletonJson(SkeletonToJson(s), kSource);
    EXPECT_EQ(t.name(), s.name());
    ASSERT_EQ(t.num_links(), s.num_links());
    EXPECT_EQ(t.root(), s.root());
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(t.link(i).name, s.link(i).name);
      EXPECT_EQ(t.link(i).parent, s.link(i).parent);
      EXPECT_EQ(t.link(i).a_L, s.link(i).a_L);  // Bit-exact.
      EXPECT_EQ(t.link(i).b_L, s.link(i).b_L);
      EXPECT_EQ(t.link(i).radius, s.link(i).radius);
    }
  }
}

TEST(SkeletonTest, LoadSkeletonFile) {
  const std::string dir = SWEPTCCD_BINARY_DIR;
  const std::string missing = dir + "/no_such_dir/no_such_skeleton.json";
  try {
    LoadSkeletonFile(missing);
    ADD_FAILURE() << "a missing file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  const std::string path = dir + "/skeleton_test_tmp.json";
  {
    std::ofstream out(path);
    out << kSpecExample;
  }
  EXPECT_EQ(LoadSkeletonFile(path).num_links(), 2);
  {
    std::ofstream out(path);
    out << Doc({Named("pelvis", "null"), Named("pelvis", "null")});
  }
  try {
    LoadSkeletonFile(path);
    ADD_FAILURE() << "a bad file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'pelvis'"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

// A chain of n links, each the child of the one before.
std::string ChainDoc(int n) {
  std::vector<Entry> entries;
  for (int i = 0; i < n; ++i) {
    entries.push_back(Named("l" + std::to_string(i), i == 0 ? "null" : "l" + std::to_string(i - 1)));
  }
  return Doc(entries);
}

// Regression: a 10,000-link chain cost 9.2 s per pair. Skeletons above the
// limit are refused with the source, the count and the flag.
TEST(SkeletonTest, LinkLimitRefusesLargerSkeletons) {
  EXPECT_EQ(ParseSkeletonJson(ChainDoc(kDefaultMaxLinks), kSource).num_links(), kDefaultMaxLinks);
  try {
    ParseSkeletonJson(ChainDoc(kDefaultMaxLinks + 1), kSource);
    ADD_FAILURE() << "257 links accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              std::string(kSource) +
                  ": 257 links, above the limit of 256; raise it with --max-links (daemon: "
                  "max_links)");
  }
  EXPECT_EQ(ParseSkeletonJson(ChainDoc(300), kSource, 300).num_links(), 300);
  EXPECT_THROW(ParseSkeletonJson(ChainDoc(3), kSource, 2), InputError);
}

TEST(SkeletonTest, FileSizeCapAndLinkLimitWhenLoading) {
  const std::string dir = ::testing::TempDir();
  const std::string chain = dir + "/sweptccd_chain_" + std::to_string(::getpid()) + ".json";
  {
    std::ofstream out(chain);
    out << ChainDoc(10);
  }
  EXPECT_EQ(LoadSkeletonFile(chain).num_links(), 10);
  try {
    LoadSkeletonFile(chain, 9);
    ADD_FAILURE() << "10 links accepted under a limit of 9";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(chain + ": 10 links, above the limit of 9"),
              std::string::npos)
        << e.what();
  }
  // A sparse file one byte over the 16 MiB cap: refused without parsing it.
  const std::string big = dir + "/sweptccd_big_" + std::to_string(::getpid()) + ".json";
  {
    std::ofstream out(big);
  }
  std::filesystem::resize_file(big, kMaxJsonFileBytes + 1);
  try {
    LoadSkeletonFile(big);
    ADD_FAILURE() << "an over-cap file accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(big + ": the skeleton file holds more than the cap of " +
                                         std::to_string(kMaxJsonFileBytes) + " bytes"),
              std::string::npos)
        << e.what();
  }
  std::remove(chain.c_str());
  std::remove(big.c_str());
}

TEST(BoundedFileTest, ReadsUpToTheCapInclusive) {
  const std::string path =
      ::testing::TempDir() + "/sweptccd_bounded_" + std::to_string(::getpid()) + ".txt";
  {
    std::ofstream out(path, std::ios::binary);
    out << std::string(100000, 'a');  // Spans chunks.
  }
  EXPECT_EQ(ReadFileBounded(path, 100000, "test file", "fix").size(), 100000u);
  try {
    ReadFileBounded(path, 99999, "test file", "the fix");
    ADD_FAILURE() << "over the cap accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": the test file holds more than the cap of 99999 bytes; the fix");
  }
  EXPECT_THROW(ReadFileBounded(path + ".missing", 10, "test file", "fix"), InputError);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace sweptccd
