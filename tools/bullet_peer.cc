#include "tools/bullet_peer.h"

#include <btBulletCollisionCommon.h>

#include <chrono>

namespace sweptccd {

struct BulletPeer::Impl {
  // Bullet keeps pointers into these: they live as long as the world.
  std::vector<std::vector<btScalar>> vertices;
  std::vector<std::vector<int>> indices;
  std::vector<std::unique_ptr<btTriangleIndexVertexArray>> arrays;
  std::vector<std::unique_ptr<btBvhTriangleMeshShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> objects;
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btCollisionWorld> world;
  // One capsule shape per link, made on first use for that skeleton
  // (radius and length do not change between poses).
  mutable std::vector<std::unique_ptr<btCapsuleShape>> capsules;
  mutable const Skeleton* capsules_for = nullptr;
};

BulletPeer::BulletPeer(const std::vector<TriangleMesh>& meshes) : impl_(std::make_unique<Impl>()) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  m.config = std::make_unique<btDefaultCollisionConfiguration>();
  m.dispatcher = std::make_unique<btCollisionDispatcher>(m.config.get());
  m.broadphase = std::make_unique<btDbvtBroadphase>();
  m.world =
      std::make_unique<btCollisionWorld>(m.dispatcher.get(), m.broadphase.get(), m.config.get());
  for (const TriangleMesh& mesh : meshes) {
    if (mesh.num_triangles() == 0) continue;
    std::vector<btScalar>& v = m.vertices.emplace_back();
    v.reserve(3 * mesh.vertices.size());
    for (const auto& p : mesh.vertices) {
      v.push_back(p.x());
      v.push_back(p.y());
      v.push_back(p.z());
    }
    std::vector<int>& ix = m.indices.emplace_back(mesh.indices.begin(), mesh.indices.end());
    auto array = std::make_unique<btTriangleIndexVertexArray>(
        static_cast<int>(mesh.num_triangles()), ix.data(), 3 * static_cast<int>(sizeof(int)),
        static_cast<int>(mesh.vertices.size()), v.data(), 3 * static_cast<int>(sizeof(btScalar)));
    auto shape = std::make_unique<btBvhTriangleMeshShape>(array.get(), true, true);
    auto object = std::make_unique<btCollisionObject>();
    object->setCollisionShape(shape.get());
    m.world->addCollisionObject(object.get());
    m.arrays.push_back(std::move(array));
    m.shapes.push_back(std::move(shape));
    m.objects.push_back(std::move(object));
  }
  m.world->updateAabbs();
  build_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

BulletPeer::~BulletPeer() {
  if (impl_ && impl_->world) {
    for (auto& o : impl_->objects) impl_->world->removeCollisionObject(o.get());
  }
}

namespace {

// The capsule's transform: centred on the segment, its Y axis (btCapsuleShape's)
// along a-b.
btTransform CapsuleTransform(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double len = d.norm();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  if (len > 0) q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitY(), d / len);
  const Eigen::Vector3d c = 0.5 * (a + b);
  return btTransform(btQuaternion(q.x(), q.y(), q.z(), q.w()), btVector3(c.x(), c.y(), c.z()));
}

}  // namespace

bool BulletPeer::Sweep(const Skeleton& skel, const Pose& pose0, const Pose& pose1) const {
  Impl& m = *impl_;
  if (m.capsules_for != &skel || static_cast<int>(m.capsules.size()) != skel.num_links()) {
    m.capsules.clear();
    for (int i = 0; i < skel.num_links(); ++i) {
      const Link& l = skel.link(i);
      m.capsules.push_back(std::make_unique<btCapsuleShape>(l.radius, (l.b_L - l.a_L).norm()));
    }
    m.capsules_for = &skel;
  }
  bool hit = false;
  for (int i = 0; i < skel.num_links(); ++i) {
    const Link& l = skel.link(i);
    const LinkPose& X0 = pose0.links[i];
    const LinkPose& X1 = pose1.links[i];
    const btTransform from = CapsuleTransform(X0.p + X0.q * l.a_L, X0.p + X0.q * l.b_L);
    const btTransform to = CapsuleTransform(X1.p + X1.q * l.a_L, X1.p + X1.q * l.b_L);
    btCollisionWorld::ClosestConvexResultCallback cb(from.getOrigin(), to.getOrigin());
    m.world->convexSweepTest(m.capsules[i].get(), from, to, cb);
    hit = hit || cb.hasHit();
  }
  return hit;
}

}  // namespace sweptccd
