#include "core/world/object_target.h"

#include <algorithm>
#include <cmath>

#include "core/geometry/distance.h"
#include "core/geometry/rounding_slack.h"
#include "core/world/entity_broad_phase.h"

namespace sweptccd::world {
namespace {

// A tracked object: one candidate (0); its triangles come from its BVH, in
// the object's frame, with A's link taken relative to the object's frame.
class ObjectTarget : public OtherTarget {
 public:
  ObjectTarget(const FilterSide& a, const ObjectWindow& o, double scale)
      : a_(a), e_(o), bvh_(e_.mesh.object(0).bvh), rho_(ObjectRadius(bvh_)) {
    if (scale < 0) scale = EntityScale(e_);
    tol_ = EntitySlack(scale, e_.mesh.coordinate_tolerance());
  }

  void RootCandidatesInto(LinkIndex link_a, std::vector<int>* out) const override {
    out->clear();
    if (bvh_.num_triangles() == 0 || IgnoresObject(a_, link_a, e_.id)) return;
    out->push_back(0);
  }

  Aabb PieceBox(const Piece& piece, double tau0, double tau1) const override {
    const RigidMotion m = MotionOf(piece.k);
    double s0 = piece.SE(tau0), s1 = piece.SE(tau1);
    WidenS(&s0, &s1);
    // Every point of the mesh is within rho of the frame origin, which moves
    // on a straight line.
    return Aabb::OfCapsule(m.PositionAt(s0), m.PositionAt(s1), rho_ * (1 + 1e-9) + tol_);
  }

  void Cull(const Piece& piece, double tau0, double tau1, const Eigen::Vector3d& a,
            const Eigen::Vector3d& b, double radius_a, double growth_a,
            std::vector<int>* cands) const override {
    if (cands->empty()) return;
    const RigidMotion m = MotionOf(piece.k);
    double s0 = piece.SE(tau0), s1 = piece.SE(tau1);
    WidenS(&s0, &s1);
    const double sm = 0.5 * (s0 + s1), hw = 0.5 * (s1 - s0);
    const Eigen::Vector3d x = m.PositionAt(sm);
    const Eigen::Matrix3d R = m.RotationAt(sm).toRotationMatrix();
    const Eigen::Vector3d a_O = R.transpose() * (a - x), b_O = R.transpose() * (b - x);
    // p_O(t) - p_O(tm) = R(t)^T [(p(t) - p(tm)) - (x(t) - x(tm))]
    //                    + (R(t) - R(tm))^T (p(tm) - x(tm)),
    // so |.| <= growth_a + |x1 - x0| hw + angle hw max|p(tm) - x(tm)|.
    const double reach = std::max((a - x).norm(), (b - x).norm());
    const double growth_o =
        (growth_a + (m.x1.p - m.x0.p).norm() * hw + m.angle * hw * reach) * (1 + 1e-9);
    const double r = radius_a + growth_o + tol_;
    bool hit = false;
    double radius = r;
    bvh_.QueryCapsuleShrinking(a_O, b_O, &radius, [&](uint32_t slot) {
      Eigen::Vector3d ta, tb, tc;
      bvh_.Triangle(slot, &ta, &tb, &tc);
      if (SegmentTriangleDistance(a_O, b_O, ta, tb, tc).distance <= r) hit = true;
      return !hit;
    });
    if (!hit) cands->clear();
  }

  bool Nearest(const Piece& piece, double tau, LinkIndex link_a, const Eigen::Vector3d& a,
               const Eigen::Vector3d& b, double radius_a, const std::vector<int>& cands,
               double search, OtherContact* out) const override {
    if (cands.empty()) return false;
    const RigidMotion m = MotionOf(piece.k);
    const double s = piece.SE(tau);
    const Eigen::Vector3d x = m.PositionAt(s);
    const Eigen::Matrix3d R = m.RotationAt(s).toRotationMatrix();
    const Eigen::Vector3d a_O = R.transpose() * (a - x), b_O = R.transpose() * (b - x);
    double radius = radius_a + std::max(search, 0.0);
    bool have = false;
    double best = HUGE_VAL;
    bvh_.QueryCapsuleShrinking(a_O, b_O, &radius, [&](uint32_t slot) {
      Eigen::Vector3d ta, tb, tc;
      bvh_.Triangle(slot, &ta, &tb, &tc);
      const SegmentTriangleResult st = SegmentTriangleDistance(a_O, b_O, ta, tb, tc);
      const double sep = st.distance - radius_a;
      if (sep <= search && sep < best) {
        best = sep;
        have = true;
        out->link = link_a;
        out->other_link = LinkIndex();
        out->triangle = bvh_.TriangleId(slot);
        out->tau = tau;
        out->point_link = x + R * st.p_segment;
        out->point_other = x + R * st.p_triangle;
        const Eigen::Vector3d face = R * (tb - ta).cross(tc - ta);
        out->normal = UnitOr(out->point_link - out->point_other, UnitOr(face, {0, 0, 1}));
        out->separation = sep;
        radius = std::min(radius, st.distance);
      }
      return true;
    });
    return have;
  }

  double tolerance() const override { return tol_; }

  // The object's box over the piece's sample interval (as WorldAnswerer
  // makes it) grown by the near margin.
  bool NearLinkBoxes(const Piece& piece, double margin, std::vector<Aabb>* boxes) const override {
    const size_t k = static_cast<size_t>(piece.k);
    const size_t k1 = std::min(k + 1, e_.samples.size() - 1);
    Aabb box = ObjectMotionBox(e_.samples[k], e_.samples[k1], rho_, bvh_.max_abs_coordinate());
    box.lo.array() -= margin;
    box.hi.array() += margin;
    boxes->assign(1, box);
    return true;
  }

 private:
  RigidMotion MotionOf(int k) const {
    const int k1 = std::min<int>(k + 1, static_cast<int>(e_.samples.size()) - 1);
    return RigidMotion(e_.samples[static_cast<size_t>(k)], e_.samples[static_cast<size_t>(k1)]);
  }

  FilterSide a_;
  ObjectWindow e_;
  const TriangleBvh& bvh_;
  double rho_ = 0;
  double tol_ = 0;
};

}  // namespace

std::unique_ptr<OtherTarget> MakeObjectTarget(const FilterSide& a, const ObjectWindow& o,
                                              double scale) {
  return std::make_unique<ObjectTarget>(a, o, scale);
}

}  // namespace sweptccd::world
