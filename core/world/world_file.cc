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

// A link of a rule, -1 for all: a JSON number is an index; text is a name
// first, then "*", then an index (ResolveLinkKey, SPEC 8 "Filters").
int ResolveLinkKey(const json& key, const Skeleton& skeleton, const std::string& where,
                   const char* field) {
  const std::string at = where + ": \"" + field + "\"";
  if (key.is_number_unsigned()) {
    return ResolveLinkIndex(
               static_cast<int64_t>(std::min<uint64_t>(key.get<uint64_t>(), INT64_MAX)), skeleton,
               at)
        .value();
  }
  if (key.is_number_integer()) return ResolveLinkIndex(key.get<int64_t>(), skeleton, at).value();
  if (!key.is_string())
    throw InputError(where + ": \"" + field + "\" must be a link name, an index or \"*\"");
  return sweptccd::ResolveLinkKey(key.get<std::string>(), skeleton, at).value();
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

LoadedWorld LoadWorldFile(const std::string& path, const WorldLoadOptions& options) {
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
  const fs::path dir = fs::path(path).parent_path();
  auto array_of = [&](const char* key) {
    if (!doc.contains(key) || doc[key].is_null()) return json::array();
    if (!doc[key].is_array()) throw InputError(path + ": \"" + key + "\" must be an array");
    return doc[key];
  };
  const json avatars = array_of("avatars"), objects = array_of("objects"), env = array_of("env");

  // Ids first: malformed or duplicate ids are refused before any file is read.
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
  std::vector<std::string> avatar_ids, object_ids;
  for (size_t i = 0; i < avatars.size(); ++i)
    avatar_ids.push_back(check_id(avatars[i], "avatars[" + std::to_string(i) + "]"));
  for (size_t i = 0; i < objects.size(); ++i)
    object_ids.push_back(check_id(objects[i], "objects[" + std::to_string(i) + "]"));

  LoadedWorld out;
  std::vector<std::string> env_paths, env_written;
  for (size_t i = 0; i < env.size(); ++i) {
    if (!env[i].is_string())
      throw InputError(path + ": env[" + std::to_string(i) + "] must be a path");
    env_written.push_back(env[i].get<std::string>());
    env_paths.push_back(Resolve(dir, env_written.back()));
    out.files.emplace_back("env[" + std::to_string(i) + "]", env_paths.back());
  }
  out.env = Environment::LoadFiles(env_paths, options.mesh);

  for (size_t i = 0; i < avatars.size(); ++i) {
    const json& e = avatars[i];
    const std::string where =
        path + ": avatars[" + std::to_string(i) + "] ('" + avatar_ids[i] + "')";
    AvatarEntity a;
    a.id = avatar_ids[i];
    const std::string role = where.substr(path.size() + 2);  // "avatars[i] ('id')".
    const std::string skeleton_path = Resolve(dir, StringField(e, "skeleton", where));
    out.files.emplace_back(role + " skeleton", skeleton_path);
    a.skeleton = LoadSkeletonFile(skeleton_path, options.max_links);
    const std::string motion = StringField(e, "motion", where, /*required=*/false);
    if (!motion.empty()) {
      const std::optional<MotionModel> m = ParseMotionModel(motion);
      if (!m)
        throw InputError(where + ": unknown motion '" + motion + "' (articulated or independent)");
      a.motion = *m;
    }
    const std::string poses_path = Resolve(dir, StringField(e, "poses", where));
    out.files.emplace_back(role + " poses", poses_path);
    ReadAvatarPoses(poses_path, &a);
    out.world.avatars.push_back(std::move(a));
  }
  for (size_t i = 0; i < objects.size(); ++i) {
    const json& e = objects[i];
    const std::string where =
        path + ": objects[" + std::to_string(i) + "] ('" + object_ids[i] + "')";
    ObjectEntity o;
    o.id = object_ids[i];
    const std::string role = where.substr(path.size() + 2);  // "objects[i] ('id')".
    const std::string mesh_path = Resolve(dir, StringField(e, "mesh", where));
    out.files.emplace_back(role + " mesh", mesh_path);
    auto mesh = std::make_shared<Environment>();
    mesh->AddMesh(LoadMeshFile(mesh_path, options.mesh), mesh_path);
    o.mesh = std::move(mesh);
    const std::string poses_path = Resolve(dir, StringField(e, "poses", where));
    out.files.emplace_back(role + " poses", poses_path);
    ReadObjectPoses(poses_path, &o);
    out.world.objects.push_back(std::move(o));
  }

  // Filters, once every skeleton is known.
  out.world.rules.resize(avatars.size());
  for (size_t i = 0; i < avatars.size(); ++i) {
    const Skeleton& skeleton = out.world.avatars[i].skeleton;
    CollisionFilter filter(skeleton.num_links(), out.env.num_objects());
    const json& e = avatars[i];
    if (e.contains("ignore") && !e["ignore"].is_null()) {
      if (!e["ignore"].is_array())
        throw InputError(path + ": avatars[" + std::to_string(i) +
                         "]: \"ignore\" must be an array");
      const json& rules = e["ignore"];
      for (size_t k = 0; k < rules.size(); ++k) {
        const std::string where = path + ": avatars[" + std::to_string(i) + "] ('" + avatar_ids[i] +
                                  "') ignore[" + std::to_string(k) + "]";
        const json& r = rules[k];
        if (!r.is_object() || !r.contains("link") ||
            (r.contains("object") == r.contains("entity"))) {
          throw InputError(
              where +
              ": a rule is {\"link\", \"object\"} or {\"link\", \"entity\"[, \"other_link\"]}");
        }
        const int link = ResolveLinkKey(r["link"], skeleton, where, "link");
        if (r.contains("object")) {
          const json& o = r["object"];
          int object = -2;
          if (o.is_number_integer() || o.is_number_unsigned()) {
            const int64_t v = o.get<int64_t>();
            if (v >= 0 && v < out.env.num_objects()) object = static_cast<int>(v);
          } else if (o.is_string()) {
            const std::string name = o.get<std::string>();
            if (name == "*") object = -1;
            for (size_t m = 0; m < env_written.size() && object == -2; ++m) {
              if (name == env_written[m] || name == env_paths[m]) object = static_cast<int>(m);
            }
          }
          if (object == -2) {
            throw InputError(where + ": unknown environment object " + o.dump() +
                             " (give an index, a path as in \"env\", or \"*\")");
          }
          filter.Ignore(link < 0 ? LinkIndex() : LinkIndex(link),
                        object < 0 ? ObjectIndex() : ObjectIndex(object));
          continue;
        }
        if (!r["entity"].is_string()) throw InputError(where + ": \"entity\" must be an id");
        EntityRule rule;
        rule.link = link;
        rule.entity = r["entity"].get<std::string>();
        if (r.contains("other_link")) {
          int other = -1;
          for (size_t b = 0; b < avatar_ids.size(); ++b) {
            if (avatar_ids[b] == rule.entity) other = static_cast<int>(b);
          }
          for (const std::string& id : object_ids) {
            if (id == rule.entity)
              throw InputError(where + ": \"other_link\" given for object '" + id +
                               "' (objects have no links)");
          }
          if (other >= 0) {
            rule.other_link = ResolveLinkKey(r["other_link"], out.world.avatars[other].skeleton,
                                             where, "other_link");
          } else if (r["other_link"].is_number_integer() && r["other_link"].get<int64_t>() >= 0) {
            rule.other_link =
                static_cast<int>(std::min<int64_t>(r["other_link"].get<int64_t>(), 1 << 30));
          } else if (!(r["other_link"].is_string())) {
            throw InputError(where + ": \"other_link\" must be a link name, an index or \"*\"");
          } else if (r["other_link"].get<std::string>() != "*") {
            rule.entity.clear();  // Names a link of an entity that never appears: never applies.
          }
        }
        if (!rule.entity.empty()) out.world.rules[i].push_back(rule);
      }
    }
    out.env_filters.push_back(std::move(filter));
  }
  return out;
}

}  // namespace sweptccd::world
