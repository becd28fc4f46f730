#include "render/contact_picture.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "render/picture_style.h"

namespace sweptccd::gpu {

namespace {

using internal::ColourJson;
using internal::Fixed;
using internal::VecJson;
using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

// Markers and the normal use pure colours that nothing lit can produce, so
// scripts can find them.
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

struct Segment {
  Eigen::Vector3d a, b;
  double radius;
};

std::vector<Segment> AvatarAt(const Skeleton& skeleton, const PairMotion& motion, double s) {
  std::vector<Segment> out;
  for (LinkIndex i(0); i < skeleton.num_links(); ++i) {
    Segment seg{{}, {}, skeleton.link(i).radius};
    motion.SegmentAt(i, s, &seg.a, &seg.b);
    out.push_back(seg);
  }
  return out;
}

DrawBatch Batch(Rgba colour, bool lit = true) {
  DrawBatch b;
  b.colour = colour;
  b.lit = lit;
  b.depth_write = colour.a == 255;
  return b;
}

void AddAvatar(const std::vector<Segment>& avatar, int slices, int stacks,
               std::vector<float>* vertices, int skip = -1) {
  for (size_t i = 0; i < avatar.size(); ++i) {
    if (static_cast<int>(i) == skip) continue;
    AppendCapsule(avatar[i].a, avatar[i].b, avatar[i].radius, slices, stacks, vertices);
  }
}

// Draws a legend swatch and label; returns the pen position after it.
int LegendItem(RgbaImage* image, int x, int y, Rgba c, const std::string& label, int scale) {
  const int h = TextHeight(scale);
  FillRect(image, x, y, x + h, y + h, Rgba{c.r, c.g, c.b, 255});
  DrawText(image, x + h + 2 * scale, y, label, kWhite, scale);
  return x + h + 2 * scale + TextWidth(label, scale) + 8 * scale;
}

// What every part of the picture is drawn from.
struct ContactScene {
  const ContactPictureOptions& o;
  const Skeleton& skeleton;
  const PairOutcome& pair;
  const QueryResult& result;
  PairMotion motion;
  Eigen::Vector3d up;
  bool has_witness;
  ContactRecord witness;
  std::vector<Segment> avatar, avatar0, avatar1;  // At the first contact, s = 0, s = 1.
  CameraView camera;
  double fit = 0.6;         // Radius around the target that the view must hold.
  double target_depth = 0;  // Eye to target.
};

// Which way the camera looks at the target (unit, from the target).
Eigen::Vector3d ViewDirection(const ContactScene& c) {
  const Eigen::Vector3d& up = c.up;
  const Eigen::Vector3d n = c.has_witness ? c.witness.normal : Eigen::Vector3d::Zero();
  const Eigen::Vector3d nh = n - n.dot(up) * up;
  if (nh.norm() > 0.3) {
    const Eigen::Vector3d h = nh.normalized();
    return (0.7 * h + up.cross(h) + 0.5 * up).normalized();
  }
  const int root = c.skeleton.root();
  Eigen::Vector3d m = c.avatar1[root].a - c.avatar0[root].a;
  m -= m.dot(up) * up;
  if (m.norm() < 1e-6) m = Eigen::Vector3d::Unit((c.o.up_axis + 1) % 3);
  m.normalize();
  const double vertical = n.dot(up) < -0.5 ? -0.6 : 0.6;  // Ceiling contact: from below.
  return (up.cross(m) + 0.35 * m + vertical * up).normalized();
}

// Camera: look at the witness (else the avatar's centre) from the side the
// normal points to, turned about 55 degrees sideways (so the link does not
// hide the triangle and the normal arrow shows its length) and raised, far
// enough to fit the avatar at the first contact. Floor or ceiling contacts:
// from the side of the walking direction, above (below for a ceiling).
void PlaceCamera(ContactScene* c) {
  const ContactPictureOptions& o = c->o;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Segment& seg : c->avatar) centre += 0.5 * (seg.a + seg.b);
  centre /= std::max<size_t>(c->avatar.size(), 1);
  CameraView& camera = c->camera;
  camera.up = c->up;
  camera.fov_y_deg = o.fov_deg;
  camera.target = o.target ? *o.target : (c->has_witness ? c->witness.point_env : centre);
  for (const Segment& seg : c->avatar) {
    c->fit = std::max({c->fit, (seg.a - camera.target).norm() + seg.radius,
                       (seg.b - camera.target).norm() + seg.radius});
  }
  const Eigen::Vector3d direction = ViewDirection(*c);
  const double aspect = static_cast<double>(o.width) / o.height;
  const double half_y = o.fov_deg * kPi / 360.0;
  const double half = std::min(half_y, std::atan(std::tan(half_y) * aspect));
  const double distance = c->fit / std::sin(half) * 1.05;
  camera.eye = o.eye ? *o.eye : Eigen::Vector3d(camera.target + distance * direction);
  c->target_depth = (camera.target - camera.eye).norm();
  camera.near_m = std::clamp(0.02 * c->target_depth, 0.01, 0.1);
  camera.far_m = c->target_depth + 2 * o.clip_radius_m + 10;
}

// Scene triangles: those within the clip radius of the target, minus those
// wholly between the camera and the avatar (nearer than the target by more
// than the avatar's reach) and those wholly above the avatar (ceilings, high
// shelves). The witness triangle is always drawn, highlighted. Appends the
// scene and witness-triangle batches; adds to `info` the counts.
void AddSceneBatches(const ContactScene& c, const Environment& env, std::vector<DrawBatch>* batches,
                     json* info) {
  double avatar_top = -INFINITY;
  for (const auto* av : {&c.avatar, &c.avatar0, &c.avatar1}) {
    for (const Segment& seg : *av) {
      avatar_top =
          std::max({avatar_top, seg.a.dot(c.up) + seg.radius, seg.b.dot(c.up) + seg.radius});
    }
  }
  const Eigen::Vector3d view = (c.camera.target - c.camera.eye).normalized();
  const double cut_depth = c.target_depth - c.fit;
  const double ceiling = avatar_top + 0.25;
  DrawBatch scene = Batch(kScene), contact_triangle = Batch(kContactTriangle);
  int64_t drawn = 0, skipped = 0;
  for (int obj = 0; obj < env.num_objects(); ++obj) {
    const TriangleBvh& bvh = env.object(obj).bvh;
    for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
      Eigen::Vector3d p[3];
      bvh.Triangle(slot, &p[0], &p[1], &p[2]);
      const bool is_witness =
          c.has_witness && obj == c.witness.object && bvh.TriangleId(slot) == c.witness.triangle;
      if (!is_witness) {
        const Eigen::Vector3d lo = p[0].cwiseMin(p[1]).cwiseMin(p[2]);
        const Eigen::Vector3d hi = p[0].cwiseMax(p[1]).cwiseMax(p[2]);
        const Eigen::Vector3d& target = c.camera.target;
        const double far_away = (target.cwiseMax(lo).cwiseMin(hi) - target).norm();
        double max_depth = -INFINITY, min_height = INFINITY;
        for (const Eigen::Vector3d& v : p) {
          max_depth = std::max(max_depth, (v - c.camera.eye).dot(view));
          min_height = std::min(min_height, v.dot(c.up));
        }
        if (far_away > c.o.clip_radius_m || max_depth < cut_depth || min_height > ceiling) {
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
  batches->push_back(std::move(scene));
  batches->push_back(std::move(contact_triangle));
  (*info)["triangles_drawn"] = drawn;
  (*info)["triangles_clipped"] = skipped;
}

// The swept volumes and both poses (translucent, after the opaque scene,
// without depth writes), then the avatar at the first contact.
void AddAvatarBatches(const ContactScene& c, std::vector<DrawBatch>* batches) {
  DrawBatch swept = Batch(kSwept, false);
  for (int k = 1; k <= c.o.swept_steps; ++k) {
    AddAvatar(AvatarAt(c.skeleton, c.motion, static_cast<double>(k) / (c.o.swept_steps + 1)), 12, 3,
              &swept.vertices);
  }
  DrawBatch pose0 = Batch(kPose0), pose1 = Batch(kPose1);
  AddAvatar(c.avatar0, 20, 6, &pose0.vertices);
  AddAvatar(c.avatar1, 20, 6, &pose1.vertices);
  batches->push_back(std::move(swept));
  batches->push_back(std::move(pose0));
  batches->push_back(std::move(pose1));
  if (!c.result.contact) return;
  // Drawn after the translucent poses (which write no depth), so it stays
  // solid where they overlap it: in a short pair they nearly coincide.
  const int touching = c.has_witness ? c.witness.link : -1;
  DrawBatch first = Batch(kFirstContact), link = Batch(kTouchingLink);
  AddAvatar(c.avatar, 24, 8, &first.vertices, touching);
  if (touching >= 0) {
    AppendCapsule(c.avatar[touching].a, c.avatar[touching].b, c.avatar[touching].radius, 24, 8,
                  &link.vertices);
  }
  batches->push_back(std::move(first));
  batches->push_back(std::move(link));
}

// The normal (an arrow from the witness on the environment) and the witness
// (a square marker in screen space), both never hidden. Returns the marker's
// description.
json AddWitnessBatches(const ContactScene& c, std::vector<DrawBatch>* batches) {
  json marker = {{"drawn", false}, {"colour", ColourJson(kMarker)}};
  if (!c.has_witness) return marker;
  const ContactRecord& w = c.witness;
  DrawBatch arrow = Batch(kNormal, false);
  arrow.depth_test = false;
  const double length = std::clamp(0.25 * c.fit, 0.15, 0.6);
  const double shaft = 0.0035 * c.target_depth;
  const Eigen::Vector3d tip = w.point_env + length * w.normal;
  const Eigen::Vector3d cone_base = w.point_env + 0.75 * length * w.normal;
  AppendCapsule(w.point_env, cone_base, shaft, 10, 2, &arrow.vertices);
  AppendCone(cone_base, tip, 3 * shaft, 16, &arrow.vertices);
  batches->push_back(std::move(arrow));
  const int width = c.o.width, height = c.o.height;
  Eigen::Vector2d pixel;
  if (!ProjectToPixel(c.camera, width, height, w.point_env, &pixel) || pixel.x() < 0 ||
      pixel.y() < 0 || pixel.x() >= width || pixel.y() >= height) {
    return marker;
  }
  const int px = static_cast<int>(std::floor(pixel.x()));
  const int py = static_cast<int>(std::floor(pixel.y()));
  DrawBatch rim = Batch(kBlack, false), dot = Batch(kMarker, false);
  rim.depth_test = dot.depth_test = false;
  rim.screen_space = dot.screen_space = true;
  AppendScreenRect(px - kMarkerRim, py - kMarkerRim, px + kMarkerRim + 1, py + kMarkerRim + 1,
                   &rim.vertices);
  AppendScreenRect(px - kMarkerHalf, py - kMarkerHalf, px + kMarkerHalf + 1, py + kMarkerHalf + 1,
                   &dot.vertices);
  batches->push_back(std::move(rim));
  batches->push_back(std::move(dot));
  return {{"drawn", true},
          {"pixel", json::array({px, py})},
          {"half_size", kMarkerHalf},
          {"colour", ColourJson(kMarker)}};
}

// Caption: what the picture shows, in words (skipped on tiny pictures).
void DrawCaption(const ContactScene& c, RgbaImage* image) {
  const int width = c.o.width;
  if (width < 480 || c.o.height < 200) return;
  const int scale = width >= 1000 ? 2 : 1;
  const int line = TextHeight(scale) + 4 * scale;
  const QueryResult& result = c.result;
  std::vector<std::string> lines;
  if (result.contact) {
    const double duration_s = PairDurationUs(c.pair.pose0.utime, c.pair.pose1.utime) * 1e-6;
    lines.push_back("pair " + std::to_string(c.pair.pair) + ": first contact at s = " +
                    Fixed(result.s_lo, 4) + " (+" + Fixed(result.s_lo * duration_s, 4) + " s)" +
                    (result.initially_colliding ? ", touching at s = 0" : "") +
                    (result.undecided ? ", undecided" : ""));
    if (c.has_witness) {
      lines.push_back("link " + c.skeleton.link(c.witness.link).name + " touches object " +
                      std::to_string(c.witness.object) + " triangle " +
                      std::to_string(c.witness.triangle) + ", separation " +
                      Fixed(c.witness.separation, 4) + " m");
    }
  } else {
    lines.push_back("pair " + std::to_string(c.pair.pair) + ": free (no contact)");
  }
  const int panel_h = line * static_cast<int>(lines.size() + 1) + 8 * scale;
  FillRect(image, 0, 0, width, panel_h, Rgba{0, 0, 0, 150});
  int y = 4 * scale;
  for (const std::string& text : lines) {
    DrawText(image, 6 * scale, y, text, kWhite, scale);
    y += line;
  }
  int x = 6 * scale;
  x = LegendItem(image, x, y, kPose0, "pose 0", scale);
  x = LegendItem(image, x, y, kPose1, "pose 1", scale);
  x = LegendItem(image, x, y, kSwept, "swept", scale);
  if (!result.contact) return;
  x = LegendItem(image, x, y, kFirstContact, "first contact", scale);
  x = LegendItem(image, x, y, kTouchingLink, "touching link", scale);
  x = LegendItem(image, x, y, kContactTriangle, "triangle", scale);
  x = LegendItem(image, x, y, kMarker, "witness", scale);
  LegendItem(image, x, y, kNormal, "normal", scale);
}

// The pair, its answer and the witness, for the sidecar.
void DescribeAnswer(const ContactScene& c, const Environment& env, json* info) {
  const QueryResult& result = c.result;
  const int64_t utime0 = c.pair.pose0.utime, utime1 = c.pair.pose1.utime;
  (*info)["pair"] = c.pair.pair;
  (*info)["utime0"] = utime0;
  (*info)["utime1"] = utime1;
  (*info)["result"] = result.contact ? "contact" : "free";
  if (result.contact) {
    (*info)["s_lo"] = result.s_lo;
    (*info)["s_hi"] = result.s_hi;
    (*info)["t_lo"] = BracketTimeLo(utime0, utime1, result.s_lo);
    (*info)["t_hi"] = BracketTimeHi(utime0, utime1, result.s_hi);
    (*info)["initially_colliding"] = result.initially_colliding;
    (*info)["undecided"] = result.undecided;
  }
  if (!c.has_witness) return;
  const ContactRecord& w = c.witness;
  (*info)["link"] = w.link.value();
  (*info)["link_name"] = c.skeleton.link(w.link).name;
  (*info)["object"] = w.object.value();
  (*info)["object_name"] = env.object(w.object).name;
  (*info)["triangle"] = w.triangle;
  (*info)["witness"] = {{"s", w.s},
                        {"point_link", VecJson(w.point_link)},
                        {"point_env", VecJson(w.point_env)},
                        {"normal", VecJson(w.normal)},
                        {"separation", w.separation}};
}

}  // namespace

ContactPicture DrawContactPicture(const ContactPictureOptions& o, const Skeleton& skeleton,
                                  const Environment& env, const PairOutcome& pair,
                                  const QueryResult& result, MotionModel model,
                                  SceneRenderer* renderer) {
  ContactScene c{o,
                 skeleton,
                 pair,
                 result,
                 PairMotion(skeleton, pair.pose0, pair.pose1, model),
                 Eigen::Vector3d::Unit(o.up_axis),
                 result.contact && !result.contacts.empty(),
                 ContactRecord{},
                 {},
                 {},
                 {},
                 CameraView{}};
  if (c.has_witness) c.witness = result.contacts[0];
  c.avatar = AvatarAt(skeleton, c.motion, result.contact ? result.s_lo : 0.5);
  c.avatar0 = AvatarAt(skeleton, c.motion, 0);
  c.avatar1 = AvatarAt(skeleton, c.motion, 1);
  PlaceCamera(&c);

  ContactPicture out;
  std::vector<DrawBatch> batches;
  AddSceneBatches(c, env, &batches, &out.info);
  AddAvatarBatches(c, &batches);
  const json marker = AddWitnessBatches(c, &batches);
  out.image = renderer->Render(batches, c.camera, o.width, o.height, kBackground);
  DrawCaption(c, &out.image);

  DescribeAnswer(c, env, &out.info);
  out.info["marker"] = marker;
  out.info["normal_colour"] = ColourJson(kNormal);
  out.info["camera"] = {{"eye", VecJson(c.camera.eye)},
                        {"target", VecJson(c.camera.target)},
                        {"up", VecJson(c.up)},
                        {"fov_deg", c.camera.fov_y_deg}};
  return out;
}

int GuessUpAxis(const Environment& env) {
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

}  // namespace sweptccd::gpu
