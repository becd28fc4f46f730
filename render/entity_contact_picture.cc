#include "render/entity_contact_picture.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/avatar/motion.h"
#include "render/picture_style.h"

namespace sweptccd::gpu {

namespace {

using internal::ColourJson;
using internal::VecJson;
using nlohmann::json;

constexpr int kCapsuleSlices = 20, kCapsuleStacks = 6;
constexpr int kMarkerHalf = 5;  // The witness markers: 11x11 pixel squares.

// The two samples of `utimes` around time t (clamped to the first and last)
// and where t lies between them, in [0, 1].
void Bracket(const std::vector<int64_t>& utimes, double t, size_t* k0, size_t* k1, double* s) {
  *k0 = *k1 = 0;
  *s = 0;
  if (utimes.size() < 2 || t <= static_cast<double>(utimes.front())) return;
  if (t >= static_cast<double>(utimes.back())) {
    *k0 = *k1 = utimes.size() - 1;
    return;
  }
  const size_t hi =
      std::upper_bound(utimes.begin(), utimes.end(), static_cast<int64_t>(t)) - utimes.begin();
  *k1 = std::min(hi, utimes.size() - 1);
  *k0 = *k1 - 1;
  const double span = static_cast<double>(utimes[*k1] - utimes[*k0]);
  *s = std::clamp((t - static_cast<double>(utimes[*k0])) / span, 0.0, 1.0);
}

// Every link of an avatar at normalised time s of (pose0, pose1), as capsules.
void AppendAvatar(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, MotionModel model,
                  double s, std::vector<float>* vertices, std::vector<Eigen::Vector3d>* points) {
  const PairMotion motion(skeleton, pose0, pose1, model);
  for (LinkIndex l(0); l < skeleton.num_links(); ++l) {
    Eigen::Vector3d a, b;
    motion.SegmentAt(l, s, &a, &b);
    AppendCapsule(a, b, skeleton.link(l).radius, kCapsuleSlices, kCapsuleStacks, vertices);
    const Eigen::Vector3d grow = Eigen::Vector3d::Constant(skeleton.link(l).radius);
    for (const Eigen::Vector3d& p : {a, b}) {
      points->push_back(p + grow);
      points->push_back(p - grow);
    }
  }
}

// A tracked object's triangles at world time t.
void AppendObject(const world::ObjectEntity& object, double t, std::vector<float>* vertices,
                  std::vector<Eigen::Vector3d>* points) {
  std::vector<int64_t> utimes;
  for (const world::RigidSample& x : object.used) utimes.push_back(x.utime);
  size_t k0, k1;
  double s;
  Bracket(utimes, t, &k0, &k1, &s);
  const world::RigidMotion motion(object.used[k0], object.used[k1]);
  const Eigen::Vector3d p = motion.PositionAt(s);
  const Eigen::Matrix3d R = motion.RotationAt(s).toRotationMatrix();
  const TriangleBvh& bvh = object.mesh->object(0).bvh;
  for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
    Eigen::Vector3d v[3];
    bvh.Triangle(slot, &v[0], &v[1], &v[2]);
    for (const Eigen::Vector3d& x : v) {
      const Eigen::Vector3d w = R * x + p;
      vertices->insert(vertices->end(), {static_cast<float>(w.x()), static_cast<float>(w.y()),
                                         static_cast<float>(w.z())});
      points->push_back(w);
    }
  }
}

// The camera: looking at `target` mostly across the contact normal (so both
// bodies are side by side), raised a little and moved towards the avatar's
// side (so that a flat object touched face-on is not seen edge-on), far
// enough to hold every point within 3 m of the target.
CameraView ChooseCamera(const EntityPictureOptions& o, const Eigen::Vector3d& target,
                        const Eigen::Vector3d& normal, const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  up[o.up_axis] = 1;
  Eigen::Vector3d across = up.cross(normal);
  if (across.norm() < 1e-6) across = up.unitOrthogonal();
  across.normalize();
  double reach = 0.3;
  for (const Eigen::Vector3d& p : points) {
    const double d = (p - target).norm();
    if (d <= 3) reach = std::max(reach, d);
  }
  const double half_fov = 0.5 * o.fov_deg * M_PI / 180;
  const double aspect = static_cast<double>(o.width) / o.height;
  const double half = std::min(half_fov, std::atan(std::tan(half_fov) * aspect));
  CameraView camera;
  camera.target = target;
  camera.up = up;
  camera.fov_y_deg = o.fov_deg;
  camera.eye =
      target + (across + 0.35 * up + 0.6 * normal).normalized() * (1.15 * reach / std::sin(half));
  camera.near_m = 0.01;
  camera.far_m = 100;
  return camera;
}

}  // namespace

EntityPicture DrawEntityPicture(const EntityPictureOptions& options, const world::World& world,
                                int a, size_t r, int b, int o, const world::OtherAnswer& answer,
                                SceneRenderer* renderer) {
  const world::AvatarEntity& avatar = world.avatars[a];
  const PairOutcome& record = avatar.records[r];
  const int64_t utime0 = record.pose0.utime, utime1 = record.pose1.utime;
  const world::OtherBracket& bracket = answer.bracket;
  const double tau = bracket.has_witness ? bracket.witness.tau : bracket.tau_lo;
  const double s = std::clamp(tau / static_cast<double>(utime1 - utime0), 0.0, 1.0);
  const double t = static_cast<double>(utime0) + tau;

  DrawBatch mine, other;
  mine.colour = kEntityAvatarColour;
  other.colour = kEntityOtherColour;
  mine.lit = other.lit = false;
  std::vector<Eigen::Vector3d> points;
  AppendAvatar(avatar.skeleton, record.pose0, record.pose1, avatar.motion, s, &mine.vertices,
               &points);
  std::string other_id;
  if (b >= 0) {
    const world::AvatarEntity& e = world.avatars[b];
    other_id = e.id;
    std::vector<int64_t> utimes;
    for (const Pose& p : e.used) utimes.push_back(p.utime);
    size_t k0, k1;
    double se;
    Bracket(utimes, t, &k0, &k1, &se);
    AppendAvatar(e.skeleton, e.used[k0], e.used[k1], e.motion, se, &other.vertices, &points);
  } else {
    other_id = world.objects[o].id;
    AppendObject(world.objects[o], t, &other.vertices, &points);
  }

  const world::OtherContact& w = bracket.witness;
  const Eigen::Vector3d target = bracket.has_witness
                                     ? Eigen::Vector3d(0.5 * (w.point_link + w.point_other))
                                 : points.empty() ? Eigen::Vector3d::Zero()
                                                  : points.front();
  CameraView camera =
      ChooseCamera(options, options.target.value_or(target),
                   bracket.has_witness ? w.normal : Eigen::Vector3d::UnitX(), points);
  if (options.eye) camera.eye = *options.eye;

  std::vector<DrawBatch> batches = {mine, other};
  json markers = json::array();
  if (bracket.has_witness) {
    DrawBatch marks;
    marks.colour = kEntityWitnessColour;
    marks.lit = false;
    marks.depth_test = false;
    marks.depth_write = false;
    marks.screen_space = true;
    for (const Eigen::Vector3d& p : {w.point_link, w.point_other}) {
      Eigen::Vector2d pixel;
      json m = {{"point", VecJson(p)}, {"drawn", false}};
      if (ProjectToPixel(camera, options.width, options.height, p, &pixel)) {
        const int px = static_cast<int>(std::floor(pixel.x()));
        const int py = static_cast<int>(std::floor(pixel.y()));
        AppendScreenRect(px - kMarkerHalf, py - kMarkerHalf, px + kMarkerHalf + 1,
                         py + kMarkerHalf + 1, &marks.vertices);
        m["drawn"] = true;
        m["pixel"] = {px, py};
      }
      markers.push_back(m);
    }
    batches.push_back(marks);
  }

  EntityPicture out;
  out.image =
      renderer->Render(batches, camera, options.width, options.height, Rgba{255, 255, 255, 255});
  out.info = {{"avatar", avatar.id},
              {"entity", other_id},
              {"pair", record.pair},
              {"utime0", utime0},
              {"utime1", utime1},
              {"tau_us", tau},
              {"s", s},
              {"link", avatar.skeleton.link(w.link).name},
              {"witness", markers},
              {"colours",
               {{"avatar", ColourJson(kEntityAvatarColour)},
                {"entity", ColourJson(kEntityOtherColour)},
                {"witness", ColourJson(kEntityWitnessColour)}}},
              {"camera", {{"eye", VecJson(camera.eye)}, {"target", VecJson(camera.target)}}}};
  if (b >= 0 && bracket.has_witness && w.other_link >= 0) {
    out.info["other_link"] = world.avatars[b].skeleton.link(w.other_link).name;
  }
  return out;
}

}  // namespace sweptccd::gpu
