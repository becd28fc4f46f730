#include "core/scene/collision_filter.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/avatar/link_key.h"
#include "core/avatar/skeleton.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/json_text.h"
#include "core/scene/environment.h"

namespace sweptccd {

CollisionFilter::CollisionFilter(int num_links, int num_objects)
    : num_links_(num_links),
      num_objects_(num_objects),
      ignored_(static_cast<size_t>(num_links) * num_objects, false) {}

void CollisionFilter::Ignore(LinkIndex link, ObjectIndex object) {
  for (int l = 0; l < num_links_; ++l) {
    if (link.is_valid() && l != link.value()) continue;
    for (int o = 0; o < num_objects_; ++o) {
      if (object.is_valid() && o != object.value()) continue;
      ignored_[static_cast<size_t>(l) * num_objects_ + o] = true;
    }
  }
}

bool CollisionFilter::IgnoresAll(LinkIndex link) const {
  // An empty filter (default constructed) ignores nothing.
  if (ignored_.empty()) return false;
  for (ObjectIndex o(0); o < num_objects_; ++o) {
    if (!Ignores(link, o)) return false;
  }
  return true;
}

namespace {

bool ParseIndex(const std::string& s, int* out) {
  if (s.empty() || s.size() > 9) return false;
  for (char c : s) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  }
  *out = std::stoi(s);
  return true;
}

ObjectIndex ResolveObject(const std::string& text, const Environment& env,
                          const std::string& where) {
  if (text == "*") return kAllObjects;
  int i;
  if (ParseIndex(text, &i)) {
    if (i < env.num_objects()) return ObjectIndex(i);
    throw InputError(where + ": object index " + text + " is out of range (there are " +
                     std::to_string(env.num_objects()) + " objects)");
  }
  i = env.FindObject(text);
  if (i >= 0) return ObjectIndex(i);
  throw InputError(where + ": unknown object '" + text + "' (give an index, a file as given, or *)");
}

std::string JsonToKey(const nlohmann::json& j, const std::string& where, const char* field) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_number_unsigned()) return std::to_string(j.get<uint64_t>());
  throw InputError(where + ": '" + field + "' must be a name, an index or \"*\"");
}

// A rule's link: a JSON number is an index; text is a name first, then "*",
// then an index (ResolveLinkKey, the one rule of SPEC 8 "Filters").
LinkIndex JsonToLink(const nlohmann::json& j, const Skeleton& skeleton, const std::string& where) {
  if (j.is_number_unsigned()) {
    return ResolveLinkIndex(static_cast<int64_t>(std::min<uint64_t>(j.get<uint64_t>(), INT64_MAX)),
                            skeleton, where);
  }
  return ResolveLinkKey(JsonToKey(j, where, "link"), skeleton, where);
}

}  // namespace

CollisionFilter CollisionFilter::FromJson(const std::string& text, const std::string& source,
                                          const Skeleton& skeleton, const Environment& env) {
  if (const std::string nul = NulByteProblem(text); !nul.empty()) {
    throw InputError(source + ": not valid JSON (" + nul + ")");
  }
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(source + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!doc.is_object() || !doc.contains("ignore") || !doc["ignore"].is_array()) {
    throw InputError(source + ": expected {\"ignore\": [{\"link\": ..., \"object\": ...}, ...]}");
  }
  CollisionFilter filter(skeleton.num_links(), env.num_objects());
  const auto& rules = doc["ignore"];
  for (size_t k = 0; k < rules.size(); ++k) {
    const std::string where = source + ": ignore[" + std::to_string(k) + "]";
    const auto& r = rules[k];
    if (!r.is_object() || !r.contains("link") || !r.contains("object")) {
      throw InputError(where + ": each rule needs \"link\" and \"object\"");
    }
    const LinkIndex link = JsonToLink(r["link"], skeleton, where);
    const ObjectIndex object = ResolveObject(JsonToKey(r["object"], where, "object"), env, where);
    filter.Ignore(link, object);
  }
  return filter;
}

CollisionFilter CollisionFilter::FromFile(const std::string& path, const Skeleton& skeleton,
                                          const Environment& env) {
  const std::string text = ReadFileBounded(path, kMaxJsonFileBytes, "filter file",
                                           "a filter file is at most a few MiB of JSON");
  return FromJson(text, path, skeleton, env);
}

void CollisionFilter::AddRule(const std::string& rule, const Skeleton& skeleton,
                              const Environment& env) {
  if (ignored_.empty()) *this = CollisionFilter(skeleton.num_links(), env.num_objects());
  const std::string where = "--ignore '" + rule + "'";
  const size_t colon = rule.rfind(':');
  if (colon == std::string::npos) throw InputError(where + ": expected LINK:OBJECT");
  Ignore(ResolveLinkKey(rule.substr(0, colon), skeleton, where),
         ResolveObject(rule.substr(colon + 1), env, where));
}

}  // namespace sweptccd
