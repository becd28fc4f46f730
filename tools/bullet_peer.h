#pragma once
// Bullet 3 peer of `sweptccd bench`: one capsule per link swept with
// btCollisionWorld::convexSweepTest from the link's pose at time 0 to its pose
// at time 1 against btBvhTriangleMeshShape copies of the scene (built once,
// outside the timing). Bullet interpolates every capsule rigidly and linearly
// between the two transforms, so its answer is not certified: a link whose
// real (articulated, slerped) path differs from the straight sweep can touch
// where Bullet sees nothing.

#include <memory>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/mesh.h"

namespace sweptccd {

class BulletPeer {
 public:
  explicit BulletPeer(const std::vector<TriangleMesh>& meshes);
  ~BulletPeer();
  BulletPeer(const BulletPeer&) = delete;
  BulletPeer& operator=(const BulletPeer&) = delete;

  double build_s() const { return build_s_; }
  /// Sweeps every link's capsule from pose0 to pose1; true when any hits.
  bool Sweep(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double build_s_ = 0;
};

}  // namespace sweptccd
