#pragma once
// Tests of the shared world: a target as another with its link boxes but
// without near boxes (core/world/near_link_boxes.h), so a test can run the
// descent as it was before them (near_link_boxes_test) or check the link
// boxes alone (entity_ccd_test).

#include <vector>

#include "core/world/other_target.h"

namespace sweptccd::world {

class WithoutNearBoxes : public OtherTarget {
 public:
  explicit WithoutNearBoxes(const OtherTarget& t) : t_(t) {}
  void RootCandidatesInto(LinkIndex link_a, std::vector<int>* out) const override {
    t_.RootCandidatesInto(link_a, out);
  }
  Aabb PieceBox(const Piece& p, double tau0, double tau1) const override {
    return t_.PieceBox(p, tau0, tau1);
  }
  bool PieceBoxMeets(const Piece& p, double tau0, double tau1, const Aabb& box) const override {
    return t_.PieceBoxMeets(p, tau0, tau1, box);
  }
  void Cull(const Piece& p, double tau0, double tau1, const Eigen::Vector3d& a,
            const Eigen::Vector3d& b, double radius_a, double growth_a,
            std::vector<int>* cands) const override {
    t_.Cull(p, tau0, tau1, a, b, radius_a, growth_a, cands);
  }
  bool Nearest(const Piece& p, double tau, LinkIndex link_a, const Eigen::Vector3d& a,
               const Eigen::Vector3d& b, double radius_a, const std::vector<int>& cands,
               double search, OtherContact* out) const override {
    return t_.Nearest(p, tau, link_a, a, b, radius_a, cands, search, out);
  }
  double tolerance() const override { return t_.tolerance(); }
  bool LinkBoxes(const Piece& p, std::vector<Aabb>* boxes) const override {
    return t_.LinkBoxes(p, boxes);
  }

 private:
  const OtherTarget& t_;
};

}  // namespace sweptccd::world
