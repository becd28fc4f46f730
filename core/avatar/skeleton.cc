#include "core/avatar/skeleton.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/geometry/interval.h"
#include "core/json_text.h"
#include "core/avatar/pose.h"

namespace sweptccd {
namespace {

std::string LinkLabel(const std::vector<Link>& links, int i) {
  std::ostringstream s;
  s << "link " << i;
  if (!links[i].name.empty()) s << " '" << links[i].name << "'";
  return s.str();
}

bool AllFinite(const Eigen::Vector3d& v) { return v.allFinite(); }

// Checks each link in index order (a name, unique; finite numbers within
// 1e9 m; radius > 0; a parent index in range, not itself; at most one root)
// and returns the root, -1 when every link has a parent. Throws InputError
// naming the first bad link.
int CheckLinksAndFindRoot(const std::vector<Link>& links, const std::string& source) {
  const int n = static_cast<int>(links.size());
  std::map<std::string, int> by_name;
  int root = -1;
  for (int i = 0; i < n; ++i) {
    const Link& l = links[i];
    const std::string who = source + ": " + LinkLabel(links, i);
    if (l.name.empty()) throw InputError(who + ": the name is empty");
    auto [it, inserted] = by_name.emplace(l.name, i);
    if (!inserted) {
      throw InputError(who + ": duplicate name (also used by link " + std::to_string(it->second) +
                       ")");
    }
    if (!AllFinite(l.a_L) || !AllFinite(l.b_L)) {
      throw InputError(who + ": 'a' or 'b' holds a non-finite number");
    }
    if (!std::isfinite(l.radius)) throw InputError(who + ": radius is not a finite number");
    if (l.a_L.cwiseAbs().maxCoeff() > kMaxCoordinate ||
        l.b_L.cwiseAbs().maxCoeff() > kMaxCoordinate || l.radius > kMaxCoordinate) {
      throw InputError(who + ": 'a', 'b' or radius is beyond 1e9 m");
    }
    if (!(l.radius > 0)) {
      throw InputError(who + ": radius must be > 0, got " + std::to_string(l.radius));
    }
    if (l.parent == i) throw InputError(who + ": the link is its own parent (a loop)");
    if (l.parent < -1 || l.parent >= n) {
      throw InputError(who + ": parent index " + std::to_string(l.parent) + " is out of range");
    }
    if (l.parent == -1) {
      if (root != -1) {
        throw InputError(who + ": second root (link " + std::to_string(root) + " '" +
                         links[root].name + "' is already the root); give it a parent");
      }
      root = i;
    }
  }
  return root;
}

// Throws InputError naming a link on a loop of parents, if any: with no root
// (`root` -1) every chain of parents loops; with one, every link must reach
// it. Precondition: parent indices in range (CheckLinksAndFindRoot).
void RefuseLoops(const std::vector<Link>& links, int root, const std::string& source) {
  const int n = static_cast<int>(links.size());
  if (root == -1) {
    // Every link has a parent, so following parents from link 0 must cycle:
    // name a link on that loop.
    std::vector<bool> seen(n, false);
    int k = 0;
    while (!seen[k]) {
      seen[k] = true;
      k = links[k].parent;
    }
    throw InputError(source + ": " + LinkLabel(links, k) +
                     ": its chain of parents forms a loop, and no link is the root "
                     "(exactly one link needs \"parent\": null)");
  }
  // Every link must reach the root by following parents; otherwise it is on a
  // loop. Linear time: each link is walked once (0 = new, 1 = on the current
  // walk, 2 = reaches the root).
  std::vector<char> state(n, 0);
  std::vector<int> walk;
  for (int i = 0; i < n; ++i) {
    walk.clear();
    int k = i;
    while (k != -1 && state[k] == 0) {
      state[k] = 1;
      walk.push_back(k);
      k = links[k].parent;
    }
    if (k != -1 && state[k] == 1) {
      throw InputError(source + ": " + LinkLabel(links, k) +
                       ": its chain of parents forms a loop and never reaches the root");
    }
    for (int w : walk) state[w] = 2;
  }
}

}  // namespace

Skeleton Skeleton::FromLinks(std::string name, std::vector<Link> links, const std::string& source) {
  const int n = static_cast<int>(links.size());
  if (n == 0) throw InputError(source + ": the skeleton has no links");
  const int root = CheckLinksAndFindRoot(links, source);
  RefuseLoops(links, root, source);
  std::vector<std::vector<int>> children(n);
  for (int i = 0; i < n; ++i) {
    if (links[i].parent >= 0) children[links[i].parent].push_back(i);
  }
  Skeleton skel;
  skel.name_ = std::move(name);
  skel.root_ = root;
  skel.order_.reserve(n);
  skel.order_.push_back(root);
  for (size_t head = 0; head < skel.order_.size(); ++head) {
    for (int c : children[skel.order_[head]]) skel.order_.push_back(c);
  }
  SWEPTCCD_CHECK(static_cast<int>(skel.order_.size()) == n);
  // Preorder with an explicit stack (chains may be deep): children pushed
  // last-first, so they come out in index order.
  skel.depth_first_.reserve(n);
  std::vector<int> stack{root};
  while (!stack.empty()) {
    const int k = stack.back();
    stack.pop_back();
    skel.depth_first_.push_back(k);
    stack.insert(stack.end(), children[k].rbegin(), children[k].rend());
  }
  SWEPTCCD_CHECK(static_cast<int>(skel.depth_first_.size()) == n);
  skel.links_ = std::move(links);
  skel.extents_.reserve(n);
  for (const Link& l : skel.links_) {
    skel.extents_.push_back(std::max(NormUpper(l.a_L.x(), l.a_L.y(), l.a_L.z()),
                                     NormUpper(l.b_L.x(), l.b_L.y(), l.b_L.z())));
  }
  return skel;
}

int Skeleton::FindLink(const std::string& name) const {
  for (int i = 0; i < num_links(); ++i) {
    if (links_[i].name == name) return i;
  }
  return -1;
}

namespace {

// For an overflow message "... parsing '1e999'": "link 'NAME': " of the link
// object around the first occurrence of that number, or "" if not found.
std::string LinkAround(const std::string& text, const std::string& message) {
  const size_t q1 = message.rfind('\'');
  const size_t q0 = q1 == std::string::npos ? q1 : message.rfind('\'', q1 - 1);
  if (q0 == std::string::npos || q1 <= q0 + 1) return {};
  const size_t at = text.find(message.substr(q0 + 1, q1 - q0 - 1));
  if (at == std::string::npos) return {};
  const size_t open = text.rfind('{', at);
  if (open == std::string::npos) return {};
  const size_t close = text.find('}', at);
  const std::string object = text.substr(open, close == std::string::npos ? std::string::npos
                                                                          : close - open);
  const size_t key = object.find("\"name\"");
  if (key == std::string::npos) return {};
  const size_t v0 = object.find('"', object.find(':', key) + 1);
  const size_t v1 = v0 == std::string::npos ? v0 : object.find('"', v0 + 1);
  if (v1 == std::string::npos) return {};
  return "link '" + object.substr(v0 + 1, v1 - v0 - 1) + "': ";
}

Eigen::Vector3d ParseVec3(const nlohmann::json& j, const std::string& who, const char* field) {
  if (!j.is_array() || j.size() != 3) {
    throw InputError(who + ": '" + field + "' must be an array of 3 numbers");
  }
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!j[k].is_number()) throw InputError(who + ": '" + field + "' must hold numbers");
    v[k] = j[k].get<double>();
    if (!std::isfinite(v[k])) throw InputError(who + ": '" + field + "' holds a non-finite number");
  }
  return v;
}

}  // namespace

Skeleton ParseSkeletonJson(const std::string& text, const std::string& source, int max_links) {
  if (const std::string nul = NulByteProblem(text); !nul.empty()) {
    throw InputError(source + ": not valid JSON (" + nul + ")");
  }
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::out_of_range& e) {
    // A number too large for a double (1e999) is the only way JSON can hold a
    // non-finite value; the parser refuses it before we see the link.
    throw InputError(source + ": " + LinkAround(text, e.what()) +
                     "non-finite number (it overflows a double): " + e.what());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(source + ": not valid JSON (" + e.what() + ")");
  }
  if (!doc.is_object()) throw InputError(source + ": the skeleton must be a JSON object");
  std::string name;
  if (doc.contains("name")) {
    if (!doc["name"].is_string()) throw InputError(source + ": 'name' must be a string");
    name = doc["name"].get<std::string>();
  }
  if (!doc.contains("links") || !doc["links"].is_array()) {
    throw InputError(source + ": missing 'links' array");
  }
  const nlohmann::json& jl = doc["links"];
  if (jl.size() > static_cast<size_t>(std::max(max_links, 1))) {
    throw InputError(source + ": " + std::to_string(jl.size()) + " links, above the limit of " +
                     std::to_string(max_links) + "; raise it with --max-links (daemon: max_links)");
  }
  std::vector<Link> links(jl.size());
  std::vector<std::string> parent_names(jl.size());
  std::vector<bool> has_parent(jl.size(), false);
  for (size_t i = 0; i < jl.size(); ++i) {
    const nlohmann::json& e = jl[i];
    std::string who = source + ": link " + std::to_string(i);
    if (!e.is_object()) throw InputError(who + ": must be a JSON object");
    if (!e.contains("name") || !e["name"].is_string()) {
      throw InputError(who + ": missing string 'name'");
    }
    links[i].name = e["name"].get<std::string>();
    who += " '" + links[i].name + "'";
    if (!e.contains("parent")) throw InputError(who + ": missing 'parent' (use null for the root)");
    if (e["parent"].is_string()) {
      parent_names[i] = e["parent"].get<std::string>();
      has_parent[i] = true;
    } else if (!e["parent"].is_null()) {
      throw InputError(who + ": 'parent' must be a link name or null");
    }
    if (!e.contains("a")) throw InputError(who + ": missing 'a'");
    if (!e.contains("b")) throw InputError(who + ": missing 'b'");
    links[i].a_L = ParseVec3(e["a"], who, "a");
    links[i].b_L = ParseVec3(e["b"], who, "b");
    if (!e.contains("radius") || !e["radius"].is_number()) {
      throw InputError(who + ": missing numeric 'radius'");
    }
    links[i].radius = e["radius"].get<double>();
  }
  // Resolve parent names (any order in the file is accepted).
  std::map<std::string, int> by_name;
  for (size_t i = 0; i < links.size(); ++i) by_name.emplace(links[i].name, static_cast<int>(i));
  for (size_t i = 0; i < links.size(); ++i) {
    if (!has_parent[i]) continue;
    auto it = by_name.find(parent_names[i]);
    if (it == by_name.end()) {
      throw InputError(source + ": link " + std::to_string(i) + " '" + links[i].name +
                       "': unknown parent '" + parent_names[i] + "'");
    }
    links[i].parent = it->second;
  }
  return Skeleton::FromLinks(std::move(name), std::move(links), source);
}

Skeleton LoadSkeletonFile(const std::string& path, int max_links) {
  const std::string text = ReadFileBounded(path, kMaxJsonFileBytes, "skeleton file",
                                           "a skeleton file is at most a few MiB of JSON");
  return ParseSkeletonJson(text, path, max_links);
}

std::string SkeletonToJson(const Skeleton& skeleton) {
  nlohmann::json doc;
  doc["name"] = skeleton.name();
  nlohmann::json links = nlohmann::json::array();
  for (const Link& l : skeleton.links()) {
    nlohmann::json e;
    e["name"] = l.name;
    e["parent"] = l.parent < 0 ? nlohmann::json(nullptr) : nlohmann::json(skeleton.link(l.parent).name);
    e["a"] = {l.a_L.x(), l.a_L.y(), l.a_L.z()};
    e["b"] = {l.b_L.x(), l.b_L.y(), l.b_L.z()};
    e["radius"] = l.radius;
    links.push_back(e);
  }
  doc["links"] = links;
  return doc.dump(2);
}

}  // namespace sweptccd
