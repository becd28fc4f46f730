#include "core/world/world_file.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "core/avatar/link_key.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/json_text.h"
#include "core/utime_json.h"

namespace sweptccd::world {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string Resolve(const fs::path& dir, const std::string& p) {
  const fs::path path(p);
  return path.is_absolute() ? p : (dir / path).lexically_normal().string();
}

std::string StringField(const json& entry, const char* key, const std::string& where,
                        bool required = true) {
  if (!entry.contains(key)) {
    if (!required) return "";
    throw InputError(where + ": missing \"" + key + "\"");
  }
  if (!entry[key].is_string()) throw InputError(where + ": \"" + key + "\" must be a string");
  return entry[key].get<std::string>();
}

// A link of a rule, kAllLinks for all: a JSON number is an index; text is a
// name first, then "*", then an index (ResolveLinkKey, SPEC 8 "Filters").
LinkIndex ResolveLinkKey(const json& key, const Skeleton& skeleton, const std::string& where,
                         const char* field) {
  const std::string at = where + ": \"" + field + "\"";
  if (key.is_number_unsigned()) {
    return ResolveLinkIndex(
        static_cast<int64_t>(std::min<uint64_t>(key.get<uint64_t>(), INT64_MAX)), skeleton, at);
  }
  if (key.is_number_integer()) return ResolveLinkIndex(key.get<int64_t>(), skeleton, at);
  if (!key.is_string())
    throw InputError(where + ": \"" + field + "\" must be a link name, an index or \"*\"");
  return sweptccd::ResolveLinkKey(key.get<std::string>(), skeleton, at);
}

void ReadAvatarPoses(const std::string& path, AvatarEntity* avatar) {
  std::ifstream in = OpenInputFile(path, "pose stream file");
  const int n = avatar->skeleton.num_links();
  PoseLineReader lines(in, n);
  PosePairer pairer;
  while (std::optional<PoseLine> line = lines.Next()) {
    std::string error = line->error;
    std::optional<Pose> pose = std::move(line->pose);
    if (pose) {
      const std::string problem = ValidateAndNormalizePose(&*pose, n);
      if (!problem.empty()) {
        error = "line " + std::to_string(line->line_number) + ": " + problem;
        pose.reset();
      }
    }
    if (pose && (avatar->used.empty() || pose->utime > avatar->used.back().utime)) {
      avatar->used.push_back(*pose);
    }
    std::optional<PairOutcome> outcome = pairer.Feed(std::move(pose), error);
    if (outcome) avatar->records.push_back(std::move(*outcome));
  }
  if (lines.bad()) throw InputError(path + ": error while reading the pose stream file");
}

void ReadObjectPoses(const std::string& path, ObjectEntity* object) {
  ReadObjectPoseFile(path, "object pose file", [object](const RigidSample& x) {
    if (object->used.empty() || x.utime > object->used.back().utime) object->used.push_back(x);
  });
}

}  // namespace

bool ParseObjectPoseLine(const std::string& line, RigidSample* sample, std::string* error) {
  if (const std::string nul = NulByteProblem(line); !nul.empty()) {
    *error = "not valid JSON (" + nul + ")";
    return false;
  }
  json j = json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object() || !j.contains("utime") || !j.contains("pose")) {
    *error = "expected {\"utime\": ..., \"pose\": [7 numbers]}";
    return false;
  }
  if (!ReadUtime(j["utime"], &sample->utime)) {  // The one utime rule of pose lines.
    *error = "utime must be an integer";
    return false;
  }
  const json& p = j["pose"];
  if (!p.is_array() || p.size() != 7) {
    *error = "pose must be 7 numbers";
    return false;
  }
  double v[7];
  for (int k = 0; k < 7; ++k) {
    if (!p[k].is_number()) {
      *error = "pose must be 7 numbers";
      return false;
    }
    v[k] = p[k].get<double>();
  }
  const int64_t utime = sample->utime;
  *error = MakeRigidSample(utime, v, sample);
  return error->empty();
}

int64_t ReadObjectPoseFile(const std::string& path, const std::string& what,
                           const std::function<void(const RigidSample&)>& usable) {
  std::ifstream in = OpenInputFile(path, what);
  int64_t unusable = 0;
  std::string line;
  bool too_long = false, blank = true;
  while (in.good() && ReadBoundedLine(in, kMaxObjectPoseLineBytes, &line, &too_long, &blank)) {
    if (blank) continue;
    RigidSample x;
    std::string error;
    if (too_long || !ParseObjectPoseLine(line, &x, &error)) {  // Not used (SPEC 8).
      ++unusable;
      continue;
    }
    usable(x);
  }
  if (in.bad()) throw InputError(path + ": error while reading the " + what);
  return unusable;
}

namespace {

// The world file's JSON, checked to be an object.
json ParseWorldDocument(const std::string& path) {
  const std::string text = ReadFileBounded(path, kMaxJsonFileBytes, "world file",
                                           "a world file is at most a few MiB of JSON");
  if (const std::string nul = NulByteProblem(text); !nul.empty()) {
    throw InputError(path + ": not valid JSON (" + nul + ")");
  }
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!doc.is_object())
    throw InputError(path + ": expected a JSON object with \"avatars\", \"objects\", \"env\"");
  return doc;
}

// The arrays of a world file and the ids of its entities, checked before any
// other file is read: malformed or duplicate ids are refused first.
struct WorldEntries {
  json avatars, objects, env;
  std::vector<std::string> avatar_ids, object_ids;
  std::vector<std::string> env_paths, env_written;  // Resolved, and as written.
};

WorldEntries CheckEntries(const json& doc, const std::string& path) {
  auto array_of = [&](const char* key) {
    if (!doc.contains(key) || doc[key].is_null()) return json::array();
    if (!doc[key].is_array()) throw InputError(path + ": \"" + key + "\" must be an array");
    return doc[key];
  };
  WorldEntries w;
  w.avatars = array_of("avatars");
  w.objects = array_of("objects");
  w.env = array_of("env");
  std::map<std::string, std::string> seen;  // id -> where
  auto check_id = [&](const json& entry, const std::string& where) {
    if (!entry.is_object()) throw InputError(path + ": " + where + " must be an object");
    const std::string id = StringField(entry, "id", path + ": " + where);
    if (!IsValidEntityId(id)) {
      throw InputError(path + ": " + where + ": malformed id '" + id +
                       "' (1-64 characters from [A-Za-z0-9_.-])");
    }
    const auto [it, inserted] = seen.emplace(id, where);
    if (!inserted) {
      throw InputError(path + ": " + where + ": duplicate id '" + id + "' (also " + it->second +
                       ")");
    }
    return id;
  };
  for (size_t i = 0; i < w.avatars.size(); ++i)
    w.avatar_ids.push_back(check_id(w.avatars[i], "avatars[" + std::to_string(i) + "]"));
  for (size_t i = 0; i < w.objects.size(); ++i)
    w.object_ids.push_back(check_id(w.objects[i], "objects[" + std::to_string(i) + "]"));
  return w;
}

// The static environment: env[i] resolved against the world file's folder.
void LoadEnv(const std::string& path, const fs::path& dir, const WorldLoadOptions& options,
             WorldEntries* w, LoadedWorld* out) {
  for (size_t i = 0; i < w->env.size(); ++i) {
    if (!w->env[i].is_string())
      throw InputError(path + ": env[" + std::to_string(i) + "] must be a path");
    w->env_written.push_back(w->env[i].get<std::string>());
    w->env_paths.push_back(Resolve(dir, w->env_written.back()));
    out->files.emplace_back("env[" + std::to_string(i) + "]", w->env_paths.back());
  }
  out->env = Environment::LoadFiles(w->env_paths, options.mesh);
}

AvatarEntity LoadAvatar(const json& e, const std::string& id, const std::string& where,
                        const std::string& role, const fs::path& dir,
                        const WorldLoadOptions& options, LoadedWorld* out) {
  AvatarEntity a;
  a.id = id;
  const std::string skeleton_path = Resolve(dir, StringField(e, "skeleton", where));
  out->files.emplace_back(role + " skeleton", skeleton_path);
  a.skeleton = LoadSkeletonFile(skeleton_path, options.max_links);
  const std::string motion = StringField(e, "motion", where, /*required=*/false);
  if (!motion.empty()) {
    const std::optional<MotionModel> m = ParseMotionModel(motion);
    if (!m)
      throw InputError(where + ": unknown motion '" + motion + "' (articulated or independent)");
    a.motion = *m;
  }
  const std::string poses_path = Resolve(dir, StringField(e, "poses", where));
  out->files.emplace_back(role + " poses", poses_path);
  ReadAvatarPoses(poses_path, &a);
  return a;
}

ObjectEntity LoadObject(const json& e, const std::string& id, const std::string& where,
                        const std::string& role, const fs::path& dir,
                        const WorldLoadOptions& options, LoadedWorld* out) {
  ObjectEntity o;
  o.id = id;
  const std::string mesh_path = Resolve(dir, StringField(e, "mesh", where));
  out->files.emplace_back(role + " mesh", mesh_path);
  auto mesh = std::make_shared<Environment>();
  mesh->AddMesh(LoadMeshFile(mesh_path, options.mesh), mesh_path);
  o.mesh = std::move(mesh);
  const std::string poses_path = Resolve(dir, StringField(e, "poses", where));
  out->files.emplace_back(role + " poses", poses_path);
  ReadObjectPoses(poses_path, &o);
  return o;
}

// An ignore rule's "object": an index, a path as in "env", or "*" (-1);
// refused when it names none.
int ResolveEnvObject(const json& o, const WorldEntries& w, int num_objects,
                     const std::string& where) {
  int object = -2;
  if (o.is_number_integer() || o.is_number_unsigned()) {
    const int64_t v = o.get<int64_t>();
    if (v >= 0 && v < num_objects) object = static_cast<int>(v);
  } else if (o.is_string()) {
    const std::string name = o.get<std::string>();
    if (name == "*") object = -1;
    for (size_t m = 0; m < w.env_written.size() && object == -2; ++m) {
      if (name == w.env_written[m] || name == w.env_paths[m]) object = static_cast<int>(m);
    }
  }
  if (object == -2) {
    throw InputError(where + ": unknown environment object " + o.dump() +
                     " (give an index, a path as in \"env\", or \"*\")");
  }
  return object;
}

// An ignore rule towards another entity ({"link", "entity"[, "other_link"]});
// its entity is cleared when it can never apply.
EntityRule ParseEntityRule(const json& r, LinkIndex link, const WorldEntries& w,
                           const std::vector<AvatarEntity>& avatars, const std::string& where) {
  if (!r["entity"].is_string()) throw InputError(where + ": \"entity\" must be an id");
  EntityRule rule;
  rule.link = link;
  rule.entity = r["entity"].get<std::string>();
  if (!r.contains("other_link")) return rule;
  int other = -1;
  for (size_t b = 0; b < w.avatar_ids.size(); ++b) {
    if (w.avatar_ids[b] == rule.entity) other = static_cast<int>(b);
  }
  for (const std::string& id : w.object_ids) {
    if (id == rule.entity)
      throw InputError(where + ": \"other_link\" given for object '" + id +
                       "' (objects have no links)");
  }
  const json& m = r["other_link"];
  if (other >= 0) {
    rule.other_link = ResolveLinkKey(m, avatars[other].skeleton, where, "other_link");
  } else if (m.is_number_integer() && m.get<int64_t>() >= 0) {
    rule.other_link = LinkIndex(static_cast<int>(std::min<int64_t>(m.get<int64_t>(), 1 << 30)));
  } else if (!(m.is_string())) {
    throw InputError(where + ": \"other_link\" must be a link name, an index or \"*\"");
  } else if (m.get<std::string>() != "*") {
    rule.entity.clear();  // Names a link of an entity that never appears: never applies.
  }
  return rule;
}

// Avatar i's "ignore" rules, once every skeleton is known: its filter against
// the static environment, and its rules towards other entities.
void ParseAvatarRules(size_t i, const std::string& path, const WorldEntries& w, LoadedWorld* out) {
  const Skeleton& skeleton = out->world.avatars[i].skeleton;
  CollisionFilter filter(skeleton.num_links(), out->env.num_objects());
  const json& e = w.avatars[i];
  if (e.contains("ignore") && !e["ignore"].is_null()) {
    if (!e["ignore"].is_array())
      throw InputError(path + ": avatars[" + std::to_string(i) + "]: \"ignore\" must be an array");
    const json& rules = e["ignore"];
    for (size_t k = 0; k < rules.size(); ++k) {
      const std::string where = path + ": avatars[" + std::to_string(i) + "] ('" + w.avatar_ids[i] +
                                "') ignore[" + std::to_string(k) + "]";
      const json& r = rules[k];
      if (!r.is_object() || !r.contains("link") || (r.contains("object") == r.contains("entity"))) {
        throw InputError(
            where +
            ": a rule is {\"link\", \"object\"} or {\"link\", \"entity\"[, \"other_link\"]}");
      }
      const LinkIndex link = ResolveLinkKey(r["link"], skeleton, where, "link");
      if (r.contains("object")) {
        const int object = ResolveEnvObject(r["object"], w, out->env.num_objects(), where);
        filter.Ignore(link, object < 0 ? ObjectIndex() : ObjectIndex(object));
        continue;
      }
      EntityRule rule = ParseEntityRule(r, link, w, out->world.avatars, where);
      if (!rule.entity.empty()) out->world.rules[i].push_back(std::move(rule));
    }
  }
  out->env_filters.push_back(std::move(filter));
}

}  // namespace

LoadedWorld LoadWorldFile(const std::string& path, const WorldLoadOptions& options) {
  const json doc = ParseWorldDocument(path);
  const fs::path dir = fs::path(path).parent_path();
  WorldEntries w = CheckEntries(doc, path);
  LoadedWorld out;
  LoadEnv(path, dir, options, &w, &out);
  for (size_t i = 0; i < w.avatars.size(); ++i) {
    const std::string where =
        path + ": avatars[" + std::to_string(i) + "] ('" + w.avatar_ids[i] + "')";
    const std::string role = where.substr(path.size() + 2);  // "avatars[i] ('id')".
    out.world.avatars.push_back(
        LoadAvatar(w.avatars[i], w.avatar_ids[i], where, role, dir, options, &out));
  }
  for (size_t i = 0; i < w.objects.size(); ++i) {
    const std::string where =
        path + ": objects[" + std::to_string(i) + "] ('" + w.object_ids[i] + "')";
    const std::string role = where.substr(path.size() + 2);  // "objects[i] ('id')".
    out.world.objects.push_back(
        LoadObject(w.objects[i], w.object_ids[i], where, role, dir, options, &out));
  }
  out.world.rules.resize(w.avatars.size());
  for (size_t i = 0; i < w.avatars.size(); ++i) ParseAvatarRules(i, path, w, &out);
  return out;
}

}  // namespace sweptccd::world
