#include "tools/render_command.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/gpu/gl_context.h"
#include "core/scene/environment.h"
#include "core/world/world_file.h"
#include "core/world/world_query.h"
#include "msgs/text.h"
#include "render/contact_picture.h"
#include "render/entity_contact_picture.h"
#include "render/raster_image.h"
#include "render/scene_renderer.h"
#include "render/timeline_picture.h"
#include "tools/output_paths.h"

namespace sweptccd {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kMinSize = 16, kMaxSize = 8192;

// Refuses an output path that cannot be written, before any long work.
void CheckWritable(const std::string& path, const std::string& flag) {
  if (path.empty()) return;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(path + ": cannot write " + flag + ": folder " + dir.string() +
                     " does not exist");
  }
  if (fs::is_directory(p, ec)) throw InputError(path + ": cannot write " + flag + ": is a folder");
  if (fs::exists(p, ec) ? ::access(path.c_str(), W_OK) != 0 : ::access(dir.c_str(), W_OK) != 0) {
    throw InputError(path + ": cannot write " + flag + ": permission denied");
  }
}

void Validate(const RenderCommandOptions& o) {
  const std::string problem = ValidateQueryOptions(o.query);
  if (!problem.empty()) throw InputError("sweptccd render: " + problem);
  const bool world = !o.world_path.empty();
  if (world) {
    if (!o.skeleton_path.empty() || !o.poses_path.empty() || !o.env_paths.empty()) {
      throw InputError(
          "sweptccd render: --world takes its skeletons, poses and meshes from the world file; "
          "drop --skeleton, --poses and --env");
    }
    if (o.avatar_id.empty() || o.entity_id.empty()) {
      throw InputError("sweptccd render: --world needs --avatar ID and --entity ID");
    }
    if (o.out_path.empty()) throw InputError("sweptccd render: --world needs --out FILE.png");
    if (!o.timeline_path.empty()) {
      throw InputError("sweptccd render: --timeline draws a pose stream, not a --world");
    }
  } else {
    if (!o.avatar_id.empty() || !o.entity_id.empty()) {
      throw InputError("sweptccd render: --avatar and --entity need --world WORLD.json");
    }
    if (o.skeleton_path.empty() || o.poses_path.empty()) {
      throw InputError(
          "sweptccd render: give --skeleton and --poses (or --world with --avatar and --entity)");
    }
    if (o.env_paths.empty()) throw InputError("sweptccd render: give at least one --env");
  }
  if (o.out_path.empty() && o.timeline_path.empty()) {
    throw InputError("sweptccd render: give --out FILE.png and/or --timeline FILE.png");
  }
  for (const auto& [name, value] : {std::pair<const char*, int>{"--width", o.width},
                                    std::pair<const char*, int>{"--height", o.height}}) {
    if (value < kMinSize || value > kMaxSize) {
      throw InputError("sweptccd render: " + std::string(name) + " " + std::to_string(value) +
                       " is outside " + std::to_string(kMinSize) + ".." + std::to_string(kMaxSize) +
                       " pixels");
    }
  }
  if (!(o.fov_deg > 1 && o.fov_deg < 170)) {
    throw InputError("sweptccd render: --fov " + std::to_string(o.fov_deg) +
                     " must be between 1 and 170 degrees");
  }
  if (o.pair < -1) throw InputError("sweptccd render: --pair must be 0 or more");
  for (const std::vector<double>* v : {&o.eye, &o.target}) {
    for (double x : *v) {
      if (!std::isfinite(x)) throw InputError("sweptccd render: --eye/--target must be finite");
    }
  }
  if (o.eye.size() == 3 && o.target.size() == 3 && o.eye == o.target) {
    throw InputError("sweptccd render: --eye and --target are the same point");
  }
  if (!(o.clip_radius_m > 0)) throw InputError("sweptccd render: --clip-radius must be > 0");
  if (!(o.max_separation_m > 0)) throw InputError("sweptccd render: --max-separation must be > 0");
  if (o.swept_steps < 0 || o.swept_steps > 200) {
    throw InputError("sweptccd render: --swept-steps must be in 0..200");
  }
  std::vector<NamedPath> inputs = {
      {"--skeleton", o.skeleton_path}, {"--poses", o.poses_path}, {"--world", o.world_path}};
  for (const std::string& e : o.env_paths) inputs.push_back({"--env", e});
  RefuseClashingPaths(
      inputs, {{"--out", o.out_path}, {"--timeline", o.timeline_path}, {"--info-out", o.info_out}});
  CheckWritable(o.out_path, "the picture (--out)");
  CheckWritable(o.timeline_path, "the timeline (--timeline)");
  CheckWritable(o.info_out, "the sidecar (--info-out)");
}

// Every record of the stream under SPEC section 2's pairing rule.
std::vector<PairOutcome> ReadPairs(const std::string& path, int num_links) {
  std::ifstream in = OpenInputFile(path, "pose stream file");
  std::vector<PairOutcome> pairs;
  PoseStreamReader reader(in, num_links);
  while (std::optional<PairOutcome> outcome = reader.Next()) pairs.push_back(std::move(*outcome));
  if (reader.bad()) throw InputError(path + ": error while reading");
  return pairs;
}

// The up axis: the flag, else the axis along which the scene is thinnest.
int UpAxis(const std::string& flag, const Environment& env) {
  if (!flag.empty()) return flag[0] - 'x';
  return gpu::GuessUpAxis(env);
}

std::optional<Eigen::Vector3d> PointFlag(const std::vector<double>& v) {
  if (v.size() != 3) return std::nullopt;
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

}  // namespace

void AddRenderOptions(CLI::App* app, RenderCommandOptions* o) {
  app->add_option("--skeleton", o->skeleton_path, "Skeleton JSON file");
  app->add_option("--poses", o->poses_path, "Pose stream, JSON Lines");
  app->add_option("--env", o->env_paths, "Mesh file (OBJ, PLY, STL, optionally .gz); repeat");
  app->add_option("--world", o->world_path,
                  "World file (SPEC 8): draw --avatar and --entity at their first contact");
  app->add_option("--avatar", o->avatar_id, "With --world: the avatar whose pairs are drawn");
  app->add_option("--entity", o->entity_id,
                  "With --world: the other avatar or tracked object it touches");
  app->add_option("--motion", o->motion, "articulated (default) or independent")
      ->check(CLI::IsMember({"articulated", "independent"}));
  app->add_option("--eps", o->query.eps_s, "Time tolerance, seconds (default 1e-4)");
  app->add_option("--delta", o->query.delta_m, "Distance tolerance, metres (default 1e-3)");
  app->add_option("--max-intervals", o->query.max_intervals, "Work limit per pair");
  app->add_option("--pair", o->pair, "Pair to draw (default: the first with contact)")
      ->check(CLI::Range(0, 2147483647));
  app->add_option("--out", o->out_path, "Picture of the contact (PNG)");
  app->add_option("--timeline", o->timeline_path, "Timeline of the whole stream (PNG)");
  app->add_option("--info-out", o->info_out, "JSON sidecar: pair, bracket, witness, marker pixel");
  app->add_option("--eye", o->eye, "Camera position x y z (default: automatic)")->expected(3);
  app->add_option("--target", o->target, "Point looked at x y z (default: the witness)")
      ->expected(3);
  app->add_option("--fov", o->fov_deg, "Vertical field of view, degrees (default 50)");
  app->add_option("--width", o->width, "Picture width, pixels (default 1280)");
  app->add_option("--height", o->height, "Picture height, pixels (default 720)");
  app->add_option("--up", o->up, "Up axis x, y or z (default: the scene's thinnest axis)")
      ->check(CLI::IsMember({"x", "y", "z"}));
  app->add_option("--clip-radius", o->clip_radius_m,
                  "Draw scene triangles within this many metres of the target (default 4)");
  app->add_option("--max-separation", o->max_separation_m,
                  "Timeline: separations clamped at this many metres (default 0.5)");
  app->add_option("--swept-steps", o->swept_steps,
                  "In-between times drawn for the swept volumes (default 12)");
  app->add_option("--max-mesh-bytes", o->mesh.max_bytes,
                  "Largest mesh file, before and after gunzip, bytes (default 1 GiB)")
      ->check(CLI::PositiveNumber);
  app->add_option("--max-links", o->max_links, "Largest skeleton, links (default 256)")
      ->check(CLI::PositiveNumber);
}

namespace {

// What both pictures are drawn from: the inputs, loaded once, and the
// answers, computed when first needed.
struct RenderInputs {
  explicit RenderInputs(const RenderCommandOptions& o)
      : skeleton(LoadSkeletonFile(o.skeleton_path, o.max_links)),
        pairs(ReadPairs(o.poses_path, skeleton.num_links())),
        env(Environment::LoadFiles(o.env_paths, o.mesh)),
        model(*ParseMotionModel(o.motion)),
        engine(skeleton, env),
        results(pairs.size()) {
    query = o.query;
    query.motion = model;
  }
  const QueryResult& Answer(size_t k) {
    if (!results[k]) results[k] = engine.Query(pairs[k].pose0, pairs[k].pose1, query);
    return *results[k];
  }

  const Skeleton skeleton;
  const std::vector<PairOutcome> pairs;
  const Environment env;
  const MotionModel model;
  QueryOptions query;
  const CcdEngine engine;
  std::vector<std::optional<QueryResult>> results;
};

// --pair, else the first pair with contact. Throws InputError.
size_t ChoosePair(const RenderCommandOptions& o, RenderInputs* in) {
  const std::vector<PairOutcome>& pairs = in->pairs;
  if (o.pair >= 0) {
    if (static_cast<size_t>(o.pair) >= pairs.size()) {
      throw InputError("sweptccd render: --pair " + std::to_string(o.pair) + " is out of range: " +
                       o.poses_path + " has " + std::to_string(pairs.size()) + " pairs (0.." +
                       std::to_string(static_cast<int64_t>(pairs.size()) - 1) + ")");
    }
    if (!pairs[o.pair].valid) {
      throw InputError("sweptccd render: --pair " + std::to_string(o.pair) +
                       " is invalid: " + pairs[o.pair].error);
    }
    return static_cast<size_t>(o.pair);
  }
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (pairs[k].valid && in->Answer(k).contact) return k;
  }
  throw InputError("sweptccd render: no contact in the stream " + o.poses_path + " (" +
                   std::to_string(pairs.size()) + " pairs)");
}

// --width/--height within what the renderer allows.
void CheckPictureSize(const RenderCommandOptions& o, gpu::SceneRenderer& renderer) {
  const int max_size = renderer.MaxSize();
  if (o.width > max_size || o.height > max_size) {
    throw InputError("sweptccd render: " + std::to_string(o.width) + "x" +
                     std::to_string(o.height) + " is larger than the renderer allows (" +
                     std::to_string(max_size) + ")");
  }
}

// --out: the contact picture. Returns its sidecar description.
json WriteContactPicture(const RenderCommandOptions& o, RenderInputs* in) {
  const size_t chosen = ChoosePair(o, in);
  gpu::GlContext context(gpu::GlContextOptions{});
  spdlog::info("render: {}", context.info().Summary());
  gpu::SceneRenderer renderer(&context);
  CheckPictureSize(o, renderer);
  gpu::ContactPictureOptions po;
  po.width = o.width;
  po.height = o.height;
  po.fov_deg = o.fov_deg;
  po.eye = PointFlag(o.eye);
  po.target = PointFlag(o.target);
  po.up_axis = UpAxis(o.up, in->env);
  po.clip_radius_m = o.clip_radius_m;
  po.swept_steps = o.swept_steps;
  const QueryResult& result = in->Answer(chosen);
  gpu::ContactPicture picture = gpu::DrawContactPicture(
      po, in->skeleton, in->env, in->pairs[chosen], result, in->model, &renderer);
  gpu::WritePngFile(o.out_path, picture.image);
  picture.info["path"] = o.out_path;
  picture.info["width"] = o.width;
  picture.info["height"] = o.height;
  picture.info["renderer"] = context.info().Summary();
  std::fprintf(stderr, "sweptccd render: pair %zu (%s) drawn to %s\n", chosen,
               result.contact ? "contact" : "free", o.out_path.c_str());
  return picture.info;
}

// --timeline: the timeline picture. Returns its sidecar description.
json WriteTimeline(const RenderCommandOptions& o, RenderInputs* in) {
  for (size_t k = 0; k < in->pairs.size(); ++k) {
    if (in->pairs[k].valid) in->Answer(k);
  }
  json timeline;
  gpu::TimelineOptions to;
  to.width = o.width;
  to.height = o.height;
  to.max_separation_m = o.max_separation_m;
  const gpu::RgbaImage image = gpu::DrawTimeline(to, in->skeleton, in->engine, in->pairs,
                                                 in->results, in->model, o.poses_path, &timeline);
  timeline["path"] = o.timeline_path;
  gpu::WritePngFile(o.timeline_path, image);
  std::fprintf(stderr, "sweptccd render: timeline of %zu pairs drawn to %s\n", in->pairs.size(),
               o.timeline_path.c_str());
  return timeline;
}

// --world: an avatar and another entity at their first contact.
json WriteEntityPicture(const RenderCommandOptions& o) {
  world::WorldLoadOptions load;
  load.mesh = o.mesh;
  load.max_links = o.max_links;
  const world::LoadedWorld loaded = world::LoadWorldFile(o.world_path, load);
  const world::World& w = loaded.world;
  int a = -1, b = -1, obj = -1;
  std::string avatars, entities;
  for (int i = 0; i < static_cast<int>(w.avatars.size()); ++i) {
    if (w.avatars[i].id == o.avatar_id) a = i;
    avatars += (avatars.empty() ? "" : ", ") + w.avatars[i].id;
  }
  if (a < 0) {
    throw InputError(o.world_path + ": --avatar '" + o.avatar_id + "' is not one of its avatars (" +
                     (avatars.empty() ? std::string("none") : avatars) + ")");
  }
  for (int i = 0; i < static_cast<int>(w.avatars.size()); ++i) {
    if (i == a) continue;
    if (w.avatars[i].id == o.entity_id) b = i;
    entities += (entities.empty() ? "" : ", ") + w.avatars[i].id;
  }
  for (int i = 0; i < static_cast<int>(w.objects.size()); ++i) {
    if (w.objects[i].id == o.entity_id) obj = i;
    entities += (entities.empty() ? "" : ", ") + w.objects[i].id;
  }
  if (b < 0 && obj < 0) {
    throw InputError(o.world_path + ": --entity '" + o.entity_id +
                     "' is not another avatar or an object of it (" +
                     (entities.empty() ? std::string("none") : entities) + ")");
  }
  const std::vector<PairOutcome>& records = w.avatars[a].records;
  QueryOptions query = o.query;
  world::WorldAnswerer answerer(loaded, query);
  world::OtherAnswer answer;
  int64_t from = 0, to = 0;
  auto contact = [&](size_t r) {
    answer = world::OtherAnswer();
    if (!records[r].valid) return false;
    const world::AvatarIndex ia(a);
    const auto e = b >= 0 ? answerer.AnswerAvatar(ia, r, world::AvatarIndex(b))
                          : answerer.AnswerObject(ia, r, world::TrackedObjectIndex(obj));
    if (!e) return false;
    answer = e->answer;
    from = e->t_from;
    to = e->t_to;
    return answer.contact;
  };
  size_t chosen = records.size();
  if (o.pair >= 0) {
    if (static_cast<size_t>(o.pair) >= records.size()) {
      throw InputError("sweptccd render: --pair " + std::to_string(o.pair) +
                       " is out of range: avatar " + o.avatar_id + " has " +
                       std::to_string(records.size()) + " pairs");
    }
    if (!contact(o.pair)) {
      throw InputError("sweptccd render: pair " + std::to_string(o.pair) + " of " + o.avatar_id +
                       " has no contact with " + o.entity_id);
    }
    chosen = o.pair;
  } else {
    for (size_t r = 0; r < records.size() && chosen == records.size(); ++r) {
      if (contact(r)) chosen = r;
    }
    if (chosen == records.size()) {
      throw InputError("sweptccd render: " + o.avatar_id + " never touches " + o.entity_id +
                       " in " + o.world_path + " (" + std::to_string(records.size()) + " pairs)");
    }
  }
  gpu::GlContext context(gpu::GlContextOptions{});
  spdlog::info("render: {}", context.info().Summary());
  gpu::SceneRenderer renderer(&context);
  CheckPictureSize(o, renderer);
  gpu::EntityPictureOptions po;
  po.width = o.width;
  po.height = o.height;
  po.fov_deg = o.fov_deg;
  po.up_axis = UpAxis(o.up, loaded.env);
  po.eye = PointFlag(o.eye);
  po.target = PointFlag(o.target);
  gpu::EntityPicture picture = gpu::DrawEntityPicture(po, w, a, chosen, b, obj, answer, &renderer);
  gpu::WritePngFile(o.out_path, picture.image);
  picture.info["path"] = o.out_path;
  picture.info["width"] = o.width;
  picture.info["height"] = o.height;
  picture.info["renderer"] = context.info().Summary();
  std::fprintf(stderr, "sweptccd render: %s and %s at pair %zu drawn to %s\n", o.avatar_id.c_str(),
               o.entity_id.c_str(), chosen, o.out_path.c_str());
  return picture.info;
}

}  // namespace

int RunRenderCommand(const RenderCommandOptions& o) {
  try {
    Validate(o);
    if (!o.world_path.empty()) {
      const json info = WriteEntityPicture(o);
      if (!o.info_out.empty()) {
        std::ofstream out(o.info_out, std::ios::binary | std::ios::trunc);
        out << info.dump(2) << '\n';
        out.flush();
        if (!out) throw InputError(o.info_out + ": error while writing the sidecar");
      }
      return 0;
    }
    RenderInputs in(o);
    json info;
    info["links"] = json::array();
    for (const Link& link : in.skeleton.links()) info["links"].push_back(link.name);
    info["pairs"] = in.pairs.size();
    if (!o.out_path.empty()) info["picture"] = WriteContactPicture(o, &in);
    if (!o.timeline_path.empty()) info["timeline"] = WriteTimeline(o, &in);
    if (!o.info_out.empty()) {
      std::ofstream out(o.info_out, std::ios::binary | std::ios::trunc);
      out << info.dump(2) << '\n';
      out.flush();
      if (!out) throw InputError(o.info_out + ": error while writing the sidecar");
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  } catch (const gpu::GpuError& e) {
    std::fprintf(stderr, "error: sweptccd render: no OpenGL picture: %s\n",
                 DisplayError(e.what()).c_str());
    return 3;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "error: out of memory\n");
    return 3;
  }
}

}  // namespace sweptccd
