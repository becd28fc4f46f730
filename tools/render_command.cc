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

#include "core/scene/environment.h"
#include "core/errors.h"
#include "core/gpu/gl_context.h"
#include "render/raster_image.h"
#include "render/scene_renderer.h"
#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "tools/output_paths.h"

namespace sweptccd {

namespace {

namespace fs = std::filesystem;
using gpu::Rgba;
using gpu::RgbaImage;
using nlohmann::json;

constexpr int kMinSize = 16, kMaxSize = 8192;
constexpr double kPi = 3.14159265358979323846;

// The contact picture. Markers and the normal use pure colours that nothing
// lit can produce, so scripts can find them.
constexpr Rgba kBackground{38, 42, 50, 255};
constexpr Rgba kScene{205, 205, 205, 255};
constexpr Rgba kContactTriangle{255, 200, 40, 255};
constexpr Rgba kPose0{70, 120, 255, 90};
constexpr Rgba kPose1{60, 210, 90, 90};
constexpr Rgba kSwept{210, 210, 255, 22};
constexpr Rgba kFirstContact{245, 140, 30, 255};
constexpr Rgba kTouchingLink{230, 30, 30, 255};
constexpr Rgba kNormal{0, 255, 255, 255};
constexpr Rgba kMarker{255, 0, 255, 255};
constexpr Rgba kBlack{0, 0, 0, 255};
constexpr Rgba kWhite{255, 255, 255, 255};
constexpr int kMarkerRim = 6;   // The marker: a 13x13 black square...
constexpr int kMarkerHalf = 4;  // ...around a 9x9 magenta one, centred on the witness.

// The timeline.
constexpr Rgba kPaper{255, 255, 255, 255};
constexpr Rgba kGrid{225, 225, 225, 255};
constexpr Rgba kContactBand{255, 200, 200, 255};
constexpr Rgba kContactMark{255, 0, 0, 255};
constexpr int kMarkHalf = 4;  // First-contact marks: 9x9 squares at the top of the plot.
// One colour per link (cycled); none is pure red (the contact marks).
constexpr Rgba kLinkColours[] = {
    {31, 119, 180, 255},  {44, 160, 44, 255},   {148, 103, 189, 255}, {140, 86, 75, 255},
    {227, 119, 194, 255}, {110, 110, 110, 255}, {188, 189, 34, 255},  {23, 190, 207, 255},
    {255, 127, 14, 255},  {0, 0, 140, 255},     {0, 128, 128, 255},   {128, 0, 128, 255},
    {90, 150, 220, 255},  {100, 200, 90, 255},  {180, 140, 60, 255},  {60, 60, 60, 255}};

json Vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }
json Colour(Rgba c) { return json::array({c.r, c.g, c.b}); }

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

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
  if (o.env_paths.empty()) throw InputError("sweptccd render: give at least one --env");
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
  std::vector<NamedPath> inputs = {{"--skeleton", o.skeleton_path}, {"--poses", o.poses_path}};
  for (const std::string& e : o.env_paths) inputs.push_back({"--env", e});
  RefuseClashingPaths(inputs, {{"--out", o.out_path},
                               {"--timeline", o.timeline_path},
                               {"--info-out", o.info_out}});
  CheckWritable(o.out_path, "the picture (--out)");
  CheckWritable(o.timeline_path, "the timeline (--timeline)");
  CheckWritable(o.info_out, "the sidecar (--info-out)");
}

// Every record of the stream under SPEC section 2's pairing rule.
std::vector<PairOutcome> ReadPairs(const std::string& path, int num_links) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the pose stream file");
  std::vector<PairOutcome> pairs;
  PoseStreamReader reader(in, num_links);
  while (std::optional<PairOutcome> outcome = reader.Next()) pairs.push_back(std::move(*outcome));
  if (reader.bad()) throw InputError(path + ": error while reading");
  return pairs;
}

// The up axis: the flag, else the axis along which the scene is thinnest
// (rooms are wider than tall), else z.
int UpAxis(const std::string& flag, const Environment& env) {
  if (!flag.empty()) return flag[0] - 'x';
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int i = 0; i < env.num_objects(); ++i) {
    const TriangleBvh& bvh = env.object(i).bvh;
    for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
      Eigen::Vector3d a, b, c;
      bvh.Triangle(slot, &a, &b, &c);
      lo = lo.cwiseMin(a).cwiseMin(b).cwiseMin(c);
      hi = hi.cwiseMax(a).cwiseMax(b).cwiseMax(c);
    }
  }
  if (!(hi.x() >= lo.x())) return 2;
  const Eigen::Vector3d extent = hi - lo;
  int axis = 2;
  if (extent.x() < extent[axis] * 0.8) axis = 0;
  if (extent.y() < extent[axis] * 0.8) axis = 1;
  return axis;
}

struct Segment {
  Eigen::Vector3d a, b;
  double radius;
};

std::vector<Segment> AvatarAt(const Skeleton& skeleton, const PairMotion& motion, double s) {
  std::vector<Segment> out;
  for (int i = 0; i < skeleton.num_links(); ++i) {
    Segment seg{{}, {}, skeleton.link(i).radius};
    motion.SegmentAt(i, s, &seg.a, &seg.b);
    out.push_back(seg);
  }
  return out;
}

gpu::DrawBatch Batch(Rgba colour, bool lit = true) {
  gpu::DrawBatch b;
  b.colour = colour;
  b.lit = lit;
  b.depth_write = colour.a == 255;
  return b;
}

void AddAvatar(const std::vector<Segment>& avatar, int slices, int stacks,
               std::vector<float>* vertices, int skip = -1) {
  for (size_t i = 0; i < avatar.size(); ++i) {
    if (static_cast<int>(i) == skip) continue;
    gpu::AppendCapsule(avatar[i].a, avatar[i].b, avatar[i].radius, slices, stacks, vertices);
  }
}

// Draws a legend swatch and label; returns the pen position after it.
int LegendItem(RgbaImage* image, int x, int y, Rgba c, const std::string& label, int scale) {
  const int h = gpu::TextHeight(scale);
  FillRect(image, x, y, x + h, y + h, Rgba{c.r, c.g, c.b, 255});
  DrawText(image, x + h + 2 * scale, y, label, kWhite, scale);
  return x + h + 2 * scale + gpu::TextWidth(label, scale) + 8 * scale;
}

struct ContactPicture {
  RgbaImage image;
  json info;
};

ContactPicture RenderContact(const RenderCommandOptions& o, const Skeleton& skeleton,
                             const Environment& env, const PairOutcome& pair,
                             const QueryResult& result, MotionModel model, int up_axis,
                             gpu::SceneRenderer* renderer) {
  const PairMotion motion(skeleton, pair.pose0, pair.pose1, model);
  const Eigen::Vector3d up = Eigen::Vector3d::Unit(up_axis);
  const bool has_witness = result.contact && !result.contacts.empty();
  const ContactRecord witness = has_witness ? result.contacts[0] : ContactRecord{};
  const double s_draw = result.contact ? result.s_lo : 0.5;
  const std::vector<Segment> avatar = AvatarAt(skeleton, motion, s_draw);
  const std::vector<Segment> avatar0 = AvatarAt(skeleton, motion, 0);
  const std::vector<Segment> avatar1 = AvatarAt(skeleton, motion, 1);

  // Camera: look at the witness (else the avatar's centre) from the side the
  // normal points to, turned about 55 degrees sideways (so the link does not
  // hide the triangle and the normal arrow shows its length) and raised, far
  // enough to fit the avatar at s_draw. Floor or ceiling contacts: from the
  // side of the walking direction, above (below for a ceiling).
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Segment& seg : avatar) centre += 0.5 * (seg.a + seg.b);
  centre /= std::max<size_t>(avatar.size(), 1);
  gpu::CameraView camera;
  camera.up = up;
  camera.fov_y_deg = o.fov_deg;
  camera.target = o.target.size() == 3 ? Eigen::Vector3d(o.target[0], o.target[1], o.target[2])
                                       : (has_witness ? witness.point_env : centre);
  double fit = 0.6;
  for (const Segment& seg : avatar) {
    fit = std::max({fit, (seg.a - camera.target).norm() + seg.radius,
                    (seg.b - camera.target).norm() + seg.radius});
  }
  Eigen::Vector3d direction;
  {
    const Eigen::Vector3d n = has_witness ? witness.normal : Eigen::Vector3d::Zero();
    const Eigen::Vector3d nh = n - n.dot(up) * up;
    if (nh.norm() > 0.3) {
      const Eigen::Vector3d h = nh.normalized();
      direction = (0.7 * h + up.cross(h) + 0.5 * up).normalized();
    } else {
      Eigen::Vector3d m = avatar1[skeleton.root()].a - avatar0[skeleton.root()].a;
      m -= m.dot(up) * up;
      if (m.norm() < 1e-6) m = Eigen::Vector3d::Unit((up_axis + 1) % 3);
      m.normalize();
      const double vertical = n.dot(up) < -0.5 ? -0.6 : 0.6;  // Ceiling contact: from below.
      direction = (up.cross(m) + 0.35 * m + vertical * up).normalized();
    }
  }
  const double aspect = static_cast<double>(o.width) / o.height;
  const double half_y = o.fov_deg * kPi / 360.0;
  const double half = std::min(half_y, std::atan(std::tan(half_y) * aspect));
  const double distance = fit / std::sin(half) * 1.05;
  camera.eye = o.eye.size() == 3 ? Eigen::Vector3d(o.eye[0], o.eye[1], o.eye[2])
                                 : Eigen::Vector3d(camera.target + distance * direction);
  const Eigen::Vector3d view = (camera.target - camera.eye).normalized();
  const double target_depth = (camera.target - camera.eye).norm();
  camera.near_m = std::clamp(0.02 * target_depth, 0.01, 0.1);
  camera.far_m = target_depth + 2 * o.clip_radius_m + 10;

  // Scene triangles: those within --clip-radius of the target, minus those
  // wholly between the camera and the avatar (nearer than the target by more
  // than the avatar's reach) and those wholly above the avatar (ceilings,
  // high shelves). The witness triangle is always drawn, highlighted.
  double avatar_top = -INFINITY;
  for (const auto* av : {&avatar, &avatar0, &avatar1}) {
    for (const Segment& seg : *av) {
      avatar_top = std::max({avatar_top, seg.a.dot(up) + seg.radius, seg.b.dot(up) + seg.radius});
    }
  }
  const double cut_depth = target_depth - fit;
  const double ceiling = avatar_top + 0.25;
  gpu::DrawBatch scene = Batch(kScene), contact_triangle = Batch(kContactTriangle);
  int64_t drawn = 0, skipped = 0;
  for (int obj = 0; obj < env.num_objects(); ++obj) {
    const TriangleBvh& bvh = env.object(obj).bvh;
    for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
      Eigen::Vector3d p[3];
      bvh.Triangle(slot, &p[0], &p[1], &p[2]);
      const bool is_witness =
          has_witness && obj == witness.object && bvh.TriangleId(slot) == witness.triangle;
      if (!is_witness) {
        const Eigen::Vector3d lo = p[0].cwiseMin(p[1]).cwiseMin(p[2]);
        const Eigen::Vector3d hi = p[0].cwiseMax(p[1]).cwiseMax(p[2]);
        const double far_away = (camera.target.cwiseMax(lo).cwiseMin(hi) - camera.target).norm();
        double max_depth = -INFINITY, min_height = INFINITY;
        for (const Eigen::Vector3d& v : p) {
          max_depth = std::max(max_depth, (v - camera.eye).dot(view));
          min_height = std::min(min_height, v.dot(up));
        }
        if (far_away > o.clip_radius_m || max_depth < cut_depth || min_height > ceiling) {
          ++skipped;
          continue;
        }
      }
      ++drawn;
      for (const Eigen::Vector3d& v : p) {
        for (int k = 0; k < 3; ++k) {
          (is_witness ? contact_triangle : scene).vertices.push_back(static_cast<float>(v[k]));
        }
      }
    }
  }

  std::vector<gpu::DrawBatch> batches;
  batches.push_back(std::move(scene));
  batches.push_back(std::move(contact_triangle));
  // Translucent parts after the opaque scene, without depth writes.
  gpu::DrawBatch swept = Batch(kSwept, false);
  for (int k = 1; k <= o.swept_steps; ++k) {
    AddAvatar(AvatarAt(skeleton, motion, static_cast<double>(k) / (o.swept_steps + 1)), 12, 3,
              &swept.vertices);
  }
  gpu::DrawBatch pose0 = Batch(kPose0), pose1 = Batch(kPose1);
  AddAvatar(avatar0, 20, 6, &pose0.vertices);
  AddAvatar(avatar1, 20, 6, &pose1.vertices);
  batches.push_back(std::move(swept));
  batches.push_back(std::move(pose0));
  batches.push_back(std::move(pose1));

  const int touching = has_witness ? witness.link : -1;
  if (result.contact) {
    // Drawn after the translucent poses (which write no depth), so it stays
    // solid where they overlap it: in a short pair they nearly coincide.
    gpu::DrawBatch first = Batch(kFirstContact), link = Batch(kTouchingLink);
    AddAvatar(avatar, 24, 8, &first.vertices, touching);
    if (touching >= 0) {
      gpu::AppendCapsule(avatar[touching].a, avatar[touching].b, avatar[touching].radius, 24, 8,
                         &link.vertices);
    }
    batches.push_back(std::move(first));
    batches.push_back(std::move(link));
  }
  json marker = {{"drawn", false}, {"colour", Colour(kMarker)}};
  if (has_witness) {
    // The normal: an arrow from the witness on the environment, never hidden.
    gpu::DrawBatch arrow = Batch(kNormal, false);
    arrow.depth_test = false;
    const double length = std::clamp(0.25 * fit, 0.15, 0.6);
    const double shaft = 0.0035 * target_depth;
    const Eigen::Vector3d tip = witness.point_env + length * witness.normal;
    const Eigen::Vector3d cone_base = witness.point_env + 0.75 * length * witness.normal;
    gpu::AppendCapsule(witness.point_env, cone_base, shaft, 10, 2, &arrow.vertices);
    gpu::AppendCone(cone_base, tip, 3 * shaft, 16, &arrow.vertices);
    batches.push_back(std::move(arrow));
    // The witness: a square marker in screen space, never hidden.
    Eigen::Vector2d pixel;
    if (ProjectToPixel(camera, o.width, o.height, witness.point_env, &pixel) && pixel.x() >= 0 &&
        pixel.y() >= 0 && pixel.x() < o.width && pixel.y() < o.height) {
      const int px = static_cast<int>(std::floor(pixel.x()));
      const int py = static_cast<int>(std::floor(pixel.y()));
      gpu::DrawBatch rim = Batch(kBlack, false), dot = Batch(kMarker, false);
      rim.depth_test = dot.depth_test = false;
      rim.screen_space = dot.screen_space = true;
      gpu::AppendScreenRect(px - kMarkerRim, py - kMarkerRim, px + kMarkerRim + 1,
                            py + kMarkerRim + 1, &rim.vertices);
      gpu::AppendScreenRect(px - kMarkerHalf, py - kMarkerHalf, px + kMarkerHalf + 1,
                            py + kMarkerHalf + 1, &dot.vertices);
      batches.push_back(std::move(rim));
      batches.push_back(std::move(dot));
      marker = {{"drawn", true},
                {"pixel", json::array({px, py})},
                {"half_size", kMarkerHalf},
                {"colour", Colour(kMarker)}};
    }
  }

  ContactPicture out;
  out.image = renderer->Render(batches, camera, o.width, o.height, kBackground);

  // Caption: what the picture shows, in words (skipped on tiny pictures).
  if (o.width >= 480 && o.height >= 200) {
    const int scale = o.width >= 1000 ? 2 : 1;
    const int line = gpu::TextHeight(scale) + 4 * scale;
    std::vector<std::string> lines;
    if (result.contact) {
      const double duration_s = PairDurationUs(pair.pose0.utime, pair.pose1.utime) * 1e-6;
      lines.push_back("pair " + std::to_string(pair.pair) + ": first contact at s = " +
                      Fixed(result.s_lo, 4) + " (+" + Fixed(result.s_lo * duration_s, 4) + " s)" +
                      (result.initially_colliding ? ", touching at s = 0" : "") +
                      (result.undecided ? ", undecided" : ""));
      if (has_witness) {
        lines.push_back("link " + skeleton.link(witness.link).name + " touches object " +
                        std::to_string(witness.object) + " triangle " +
                        std::to_string(witness.triangle) + ", separation " +
                        Fixed(witness.separation, 4) + " m");
      }
    } else {
      lines.push_back("pair " + std::to_string(pair.pair) + ": free (no contact)");
    }
    const int panel_h = line * static_cast<int>(lines.size() + 1) + 8 * scale;
    FillRect(&out.image, 0, 0, o.width, panel_h, Rgba{0, 0, 0, 150});
    int y = 4 * scale;
    for (const std::string& text : lines) {
      DrawText(&out.image, 6 * scale, y, text, kWhite, scale);
      y += line;
    }
    int x = 6 * scale;
    x = LegendItem(&out.image, x, y, kPose0, "pose 0", scale);
    x = LegendItem(&out.image, x, y, kPose1, "pose 1", scale);
    x = LegendItem(&out.image, x, y, kSwept, "swept", scale);
    if (result.contact) {
      x = LegendItem(&out.image, x, y, kFirstContact, "first contact", scale);
      x = LegendItem(&out.image, x, y, kTouchingLink, "touching link", scale);
      x = LegendItem(&out.image, x, y, kContactTriangle, "triangle", scale);
      x = LegendItem(&out.image, x, y, kMarker, "witness", scale);
      LegendItem(&out.image, x, y, kNormal, "normal", scale);
    }
  }

  json& info = out.info;
  info["pair"] = pair.pair;
  info["utime0"] = pair.pose0.utime;
  info["utime1"] = pair.pose1.utime;
  info["result"] = result.contact ? "contact" : "free";
  if (result.contact) {
    info["s_lo"] = result.s_lo;
    info["s_hi"] = result.s_hi;
    info["t_lo"] = BracketTimeLo(pair.pose0.utime, pair.pose1.utime, result.s_lo);
    info["t_hi"] = BracketTimeHi(pair.pose0.utime, pair.pose1.utime, result.s_hi);
    info["initially_colliding"] = result.initially_colliding;
    info["undecided"] = result.undecided;
  }
  if (has_witness) {
    info["link"] = witness.link.value();
    info["link_name"] = skeleton.link(witness.link).name;
    info["object"] = witness.object.value();
    info["object_name"] = env.object(witness.object).name;
    info["triangle"] = witness.triangle;
    info["witness"] = {{"s", witness.s},
                       {"point_link", Vec(witness.point_link)},
                       {"point_env", Vec(witness.point_env)},
                       {"normal", Vec(witness.normal)},
                       {"separation", witness.separation}};
  }
  info["marker"] = marker;
  info["normal_colour"] = Colour(kNormal);
  info["camera"] = {{"eye", Vec(camera.eye)},
                    {"target", Vec(camera.target)},
                    {"up", Vec(up)},
                    {"fov_deg", camera.fov_y_deg}};
  info["triangles_drawn"] = drawn;
  info["triangles_clipped"] = skipped;
  return out;
}

struct TimelineSample {
  double t_s;
  std::vector<double> separation;  // Per link, clamped to [0, max].
};

RgbaImage RenderTimeline(const RenderCommandOptions& o, const Skeleton& skeleton,
                         const CcdEngine& engine, const std::vector<PairOutcome>& pairs,
                         const std::vector<std::optional<QueryResult>>& results, MotionModel model,
                         json* info) {
  const int n = skeleton.num_links();
  const double max_sep = o.max_separation_m;
  int64_t utime_start = 0, utime_end = 0;
  bool any = false;
  for (const PairOutcome& p : pairs) {
    if (!p.valid) continue;
    if (!any) utime_start = p.pose0.utime;
    utime_end = p.pose1.utime;
    any = true;
  }
  if (!any) throw InputError(o.poses_path + ": no valid pair in the stream for the timeline");
  auto seconds = [&](double utime) { return (utime - static_cast<double>(utime_start)) * 1e-6; };
  const double span_s = std::max(seconds(static_cast<double>(utime_end)), 1e-6);

  // Separations at s = 0 of every pair, at s = 1 of the last one, and at the
  // first contact of pairs with contact.
  std::vector<TimelineSample> samples;
  auto sample = [&](const PairMotion& motion, double s, double utime) {
    TimelineSample ts{seconds(utime), std::vector<double>(n, max_sep)};
    for (int link = 0; link < n; ++link) {
      ContactRecord record;
      if (engine.Separation(motion, LinkIndex(link), s, max_sep, &record)) {
        ts.separation[link] = std::clamp(record.separation, 0.0, max_sep);
      }
    }
    samples.push_back(std::move(ts));
  };
  size_t last_valid = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (pairs[k].valid) last_valid = k;
  }
  for (size_t k = 0; k < pairs.size(); ++k) {
    const PairOutcome& p = pairs[k];
    if (!p.valid) continue;
    const PairMotion motion(skeleton, p.pose0, p.pose1, model);
    const double duration = static_cast<double>(p.pose1.utime - p.pose0.utime);
    sample(motion, 0, static_cast<double>(p.pose0.utime));
    if (results[k]->contact && results[k]->s_lo > 0) {
      sample(motion, results[k]->s_lo, p.pose0.utime + results[k]->s_lo * duration);
    }
    if (k == last_valid) sample(motion, 1, static_cast<double>(p.pose1.utime));
  }

  // Layout.
  const int scale = o.width >= 1000 ? 2 : 1;
  const int th = gpu::TextHeight(scale);
  int legend_w = 0;
  for (int i = 0; i < n; ++i)
    legend_w = std::max(legend_w, gpu::TextWidth(skeleton.link(i).name, scale));
  const int x0 = 12 * scale + gpu::TextWidth("0.50", scale) + 8 * scale;
  const int x1 = o.width - (legend_w + th + 24 * scale);
  const int y0 = 4 * th + 16 * scale;
  const int y1 = o.height - (2 * th + 20 * scale);
  const int legend_rows_fit = (o.height - y0) / (th + 4 * scale);
  if (x1 - x0 < 100 || y1 - y0 < 60 || legend_rows_fit < n) {
    throw InputError("sweptccd render: --width/--height " + std::to_string(o.width) + "x" +
                     std::to_string(o.height) + " is too small for the timeline (try 1280x720)");
  }
  auto x_of = [&](double t_s) { return x0 + t_s / span_s * (x1 - x0); };
  auto y_of = [&](double sep) { return y1 - std::clamp(sep, 0.0, max_sep) / max_sep * (y1 - y0); };

  RgbaImage image(o.width, o.height, kPaper);
  DrawText(&image, x0, 6 * scale,
           "separation from the environment per link (m, clamped at " + Fixed(max_sep, 2) +
               ") against time (s)",
           kBlack, scale);
  DrawText(&image, x0, 6 * scale + th + 4 * scale,
           "red bands: pairs with contact; red marks: first contact (t_lo)", kContactMark, scale);
  // Contact bands.
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!pairs[k].valid || !results[k]->contact) continue;
    const int bx0 =
        static_cast<int>(std::floor(x_of(seconds(static_cast<double>(pairs[k].pose0.utime)))));
    const int bx1 =
        static_cast<int>(std::ceil(x_of(seconds(static_cast<double>(pairs[k].pose1.utime)))));
    FillRect(&image, bx0, y0, std::max(bx1, bx0 + 2), y1, kContactBand);
  }
  // Grid and axes.
  const int y_ticks = 5;
  for (int i = 0; i <= y_ticks; ++i) {
    const double sep = max_sep * i / y_ticks;
    const int y = static_cast<int>(std::lround(y_of(sep)));
    DrawLine(&image, x0, y, x1, y, kGrid);
    const std::string label = Fixed(sep, 2);
    DrawText(&image, x0 - 6 * scale - gpu::TextWidth(label, scale), y - th / 2, label, kBlack,
             scale);
  }
  const double steps[] = {0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 30, 60, 120, 300, 600, 1800, 3600};
  double step = steps[0];
  for (double s : steps) {
    step = s;
    if (span_s / s <= 12) break;
  }
  for (int i = 0; i * step <= span_s + 1e-9; ++i) {
    const int x = static_cast<int>(std::lround(x_of(i * step)));
    DrawLine(&image, x, y0, x, y1, kGrid);
    DrawLine(&image, x, y1, x, y1 + 4 * scale, kBlack);
    const std::string label = Fixed(i * step, step < 1 ? (step < 0.1 ? 2 : 1) : 0);
    DrawText(&image, x - gpu::TextWidth(label, scale) / 2, y1 + 7 * scale, label, kBlack, scale);
  }
  DrawLine(&image, x0, y0, x0, y1, kBlack);
  DrawLine(&image, x0, y1, x1, y1, kBlack);
  DrawText(&image, (x0 + x1) / 2 - gpu::TextWidth("time (s)", scale) / 2, y1 + th + 12 * scale,
           "time (s)", kBlack, scale);
  DrawText(&image, 4 * scale, y0 - th - 8 * scale, "separation (m)", kBlack, scale);
  // One line per link.
  for (int link = 0; link < n; ++link) {
    const Rgba c = kLinkColours[link % std::size(kLinkColours)];
    for (size_t i = 1; i < samples.size(); ++i) {
      DrawLine(&image, x_of(samples[i - 1].t_s), y_of(samples[i - 1].separation[link]),
               x_of(samples[i].t_s), y_of(samples[i].separation[link]), c, scale);
    }
  }
  // Legend.
  for (int link = 0; link < n; ++link) {
    const int y = y0 + link * (th + 4 * scale);
    const Rgba c = kLinkColours[link % std::size(kLinkColours)];
    FillRect(&image, x1 + 10 * scale, y, x1 + 10 * scale + th, y + th, c);
    DrawText(&image, x1 + 12 * scale + th, y, skeleton.link(link).name, c, scale);
  }
  // First-contact marks, last so nothing covers them.
  json marks = json::array();
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!pairs[k].valid || !results[k]->contact) continue;
    const PairOutcome& p = pairs[k];
    const double t_lo =
        p.pose0.utime + results[k]->s_lo * static_cast<double>(p.pose1.utime - p.pose0.utime);
    const int x = std::clamp(static_cast<int>(std::lround(x_of(seconds(t_lo)))), x0, x1);
    const int y = y0 + kMarkHalf + 2;
    DrawLine(&image, x, y0, x, y1, kContactMark);
    FillRect(&image, x - kMarkHalf, y - kMarkHalf, x + kMarkHalf + 1, y + kMarkHalf + 1,
             kContactMark);
    marks.push_back({{"pair", p.pair}, {"t_lo_s", seconds(t_lo)}, {"pixel", json::array({x, y})}});
  }
  (*info)["path"] = o.timeline_path;
  (*info)["width"] = o.width;
  (*info)["height"] = o.height;
  (*info)["plot"] = json::array({x0, y0, x1, y1});
  (*info)["max_separation"] = max_sep;
  (*info)["mark_colour"] = Colour(kContactMark);
  (*info)["band_colour"] = Colour(kContactBand);
  (*info)["contact_marks"] = marks;
  json sampled = json::array();
  for (const TimelineSample& ts : samples) {
    sampled.push_back({{"t_s", ts.t_s}, {"separation", ts.separation}});
  }
  (*info)["samples"] = sampled;
  return image;
}

}  // namespace

void AddRenderOptions(CLI::App* app, RenderCommandOptions* o) {
  app->add_option("--skeleton", o->skeleton_path, "Skeleton JSON file")->required();
  app->add_option("--poses", o->poses_path, "Pose stream, JSON Lines")->required();
  app->add_option("--env", o->env_paths, "Mesh file (OBJ, PLY, STL, optionally .gz); repeat")
      ->required();
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
}

int RunRenderCommand(const RenderCommandOptions& o) {
  try {
    Validate(o);
    const Skeleton skeleton = LoadSkeletonFile(o.skeleton_path);
    const std::vector<PairOutcome> pairs = ReadPairs(o.poses_path, skeleton.num_links());
    const Environment env = Environment::LoadFiles(o.env_paths);
    const MotionModel model = *ParseMotionModel(o.motion);
    QueryOptions query = o.query;
    query.motion = model;
    const CcdEngine engine(skeleton, env);
    std::vector<std::optional<QueryResult>> results(pairs.size());
    auto answer = [&](size_t k) -> const QueryResult& {
      if (!results[k]) results[k] = engine.Query(pairs[k].pose0, pairs[k].pose1, query);
      return *results[k];
    };

    json info;
    info["links"] = json::array();
    for (const Link& link : skeleton.links()) info["links"].push_back(link.name);
    info["pairs"] = pairs.size();

    if (!o.out_path.empty()) {
      int chosen = -1;
      if (o.pair >= 0) {
        if (static_cast<size_t>(o.pair) >= pairs.size()) {
          throw InputError("sweptccd render: --pair " + std::to_string(o.pair) +
                           " is out of range: " + o.poses_path + " has " +
                           std::to_string(pairs.size()) + " pairs (0.." +
                           std::to_string(static_cast<int64_t>(pairs.size()) - 1) + ")");
        }
        if (!pairs[o.pair].valid) {
          throw InputError("sweptccd render: --pair " + std::to_string(o.pair) +
                           " is invalid: " + pairs[o.pair].error);
        }
        chosen = o.pair;
      } else {
        for (size_t k = 0; k < pairs.size() && chosen < 0; ++k) {
          if (pairs[k].valid && answer(k).contact) chosen = static_cast<int>(k);
        }
        if (chosen < 0) {
          throw InputError("sweptccd render: no contact in the stream " + o.poses_path + " (" +
                           std::to_string(pairs.size()) + " pairs)");
        }
      }
      gpu::GlContext context(gpu::GlContextOptions{});
      spdlog::info("render: {}", context.info().Summary());
      gpu::SceneRenderer renderer(&context);
      const int max_size = renderer.MaxSize();
      if (o.width > max_size || o.height > max_size) {
        throw InputError("sweptccd render: " + std::to_string(o.width) + "x" +
                         std::to_string(o.height) + " is larger than the renderer allows (" +
                         std::to_string(max_size) + ")");
      }
      ContactPicture picture = RenderContact(o, skeleton, env, pairs[chosen], answer(chosen), model,
                                             UpAxis(o.up, env), &renderer);
      gpu::WritePngFile(o.out_path, picture.image);
      picture.info["path"] = o.out_path;
      picture.info["width"] = o.width;
      picture.info["height"] = o.height;
      picture.info["renderer"] = context.info().Summary();
      info["picture"] = picture.info;
      std::fprintf(stderr, "sweptccd render: pair %d (%s) drawn to %s\n", chosen,
                   answer(chosen).contact ? "contact" : "free", o.out_path.c_str());
    }
    if (!o.timeline_path.empty()) {
      for (size_t k = 0; k < pairs.size(); ++k) {
        if (pairs[k].valid) answer(k);
      }
      json timeline;
      const RgbaImage image = RenderTimeline(o, skeleton, engine, pairs, results, model, &timeline);
      gpu::WritePngFile(o.timeline_path, image);
      info["timeline"] = timeline;
      std::fprintf(stderr, "sweptccd render: timeline of %zu pairs drawn to %s\n", pairs.size(),
                   o.timeline_path.c_str());
    }
    if (!o.info_out.empty()) {
      std::ofstream out(o.info_out, std::ios::binary | std::ios::trunc);
      out << info.dump(2) << '\n';
      out.flush();
      if (!out) throw InputError(o.info_out + ": error while writing the sidecar");
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const gpu::GpuError& e) {
    std::fprintf(stderr, "error: sweptccd render: no OpenGL picture: %s\n", e.what());
    return 3;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "error: out of memory\n");
    return 3;
  }
}

}  // namespace sweptccd
