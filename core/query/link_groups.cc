#include "core/query/link_groups.h"

#include <algorithm>

#include "core/errors.h"
#include "core/geometry/interval.h"
#include "core/geometry/rounding_slack.h"

namespace sweptccd::internal {

LinkGroups::LinkGroups(const Skeleton& skeleton) {
  const int n = skeleton.num_links();
  std::vector<std::vector<LinkIndex>> children(n);
  std::vector<LinkIndex> roots;
  for (LinkIndex l(0); l < n; ++l) {
    const int parent = skeleton.link(l).parent;
    if (parent < 0) {
      roots.push_back(l);
    } else {
      children[parent].push_back(l);
    }
  }
  // Preorder, iteratively (chains may be deep), children in index order.
  preorder_.reserve(n);
  std::vector<LinkIndex> stack(roots.rbegin(), roots.rend());
  while (!stack.empty()) {
    const LinkIndex l = stack.back();
    stack.pop_back();
    preorder_.push_back(l);
    for (auto c = children[l].rbegin(); c != children[l].rend(); ++c) stack.push_back(*c);
  }
  SWEPTCCD_CHECK(static_cast<int>(preorder_.size()) == n);
  children_ = children;
  position_.assign(n, 0);
  for (int i = 0; i < n; ++i) position_[preorder_[i]] = i;
  subtree_size_.assign(n, 1);
  for (int i = n - 1; i >= 0; --i) {  // Descendants before their ancestors.
    const int parent = skeleton.link(preorder_[i]).parent;
    if (parent >= 0) subtree_size_[parent] += subtree_size_[preorder_[i]];
  }
  // Children before parents: a link whose only child roots a group adds one
  // link to that group and a wider ball, so only the child roots one (an
  // arm's chain is one group at the forearm, whose children are the hand).
  is_root_.assign(n, false);
  for (int i = n - 1; i >= 0; --i) {
    const LinkIndex l = preorder_[i];
    const bool chain = children[l].size() == 1 && is_root_[children[l][0]];
    is_root_[l] = skeleton.link(l).parent >= 0 && subtree_size_[l] >= kMinLinks && !chain;
    num_groups_ += is_root_[l] ? 1 : 0;
  }
  std::vector<double> rest(n, 0.0);  // Children first: the reach at rest.
  for (int i = n - 1; i >= 0; --i) {
    const LinkIndex l = preorder_[i];
    rest[l] = std::max(rest[l], skeleton.extent(l) + skeleton.link(l).radius);
    const int parent = skeleton.link(l).parent;
    if (parent >= 0) rest[parent] = std::max(rest[parent], skeleton.extent(parent) + rest[l]);
  }
  std::vector<bool> top(n, false);
  for (const LinkIndex l : preorder_) {  // Parents first.
    bool held = false;
    for (int k = skeleton.link(l).parent; k >= 0 && !held; k = skeleton.link(k).parent) {
      held = top[k];
    }
    top[l] = is_root_[l] && !held && rest[l] <= kTopReachM;
    if (top[l]) top_roots_.push_back(l);
  }
}

namespace {
[[gnu::always_inline]] inline double Norm(const Eigen::Vector3d& v) {
  return NormUpper(v.x(), v.y(), v.z());
}
// Upper end of max |u(t) - v(t)| over t in [0, 1] for u, v interpolated
// linearly between their ends (u0, u1) and (v0, v1): u - v is too, so its
// norm peaks at an end.
[[gnu::always_inline]] inline double Apart(const Eigen::Vector3d& u0, const Eigen::Vector3d& u1,
                                           const Eigen::Vector3d& v0, const Eigen::Vector3d& v1) {
  return std::max(Norm(u0 - v0), Norm(u1 - v1));
}
// From child c's origin, the farthest point of its parent d's whole-pair
// capsule: c's offset and d's segment ends are fixed or interpolated in d's
// frame, so |c(t) - a| <= max(|c0 - a|, |c1 - a|), and the capsule adds
// d's radius and growth (as own(d)).
double OwnFromChild(const Skeleton& skeleton, const PairMotion& motion,
                    const std::vector<double>& growth, LinkIndex d, LinkIndex c) {
  const Link& link = skeleton.link(d);
  const Eigen::Vector3d& c0 = motion.offset(c, 0);
  const Eigen::Vector3d& c1 = motion.offset(c, 1);
  const double far = std::max(Apart(c0, c1, link.a_L, link.a_L), Apart(c0, c1, link.b_L, link.b_L));
  return far + link.radius + growth[d];
}
}  // namespace

void SubtreeReach(const LinkGroups& groups, const Skeleton& skeleton, const PairMotion& motion,
                  std::vector<double>* reach, std::vector<double>* growth) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  const std::vector<LinkIndex>& order = groups.preorder();
  reach->assign(order.size(), 0.0);
  motion.PairGrowthUppers(growth);                            // Needs no complete motion.
  for (auto it = order.rbegin(); it != order.rend(); ++it) {  // Children first.
    const LinkIndex j = *it;
    const double g = (*growth)[j];
    const double own = skeleton.extent(j) + skeleton.link(j).radius + g;
    double& r = (*reach)[j];
    r = std::max(r, own);
    const int parent = skeleton.link(j).parent;
    if (parent >= 0) {
      double& up = (*reach)[parent];
      up = std::max(up, motion.lever(j) + r);
    }
  }
}

LinkIndex BallCentre(const LinkGroups& groups, const Skeleton& skeleton, const PairMotion& motion,
                     const std::vector<double>& reach, const std::vector<double>& growth,
                     LinkIndex root, double* radius) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  LinkIndex d = root;
  double bound = reach[root];
  double up = 0;  // Bounds the distance from d's origin to members outside d's subtree.
  for (int step = 0; step < kMaxCentreSteps; ++step) {
    const std::vector<LinkIndex>& kids = groups.children(d);
    if (kids.empty()) break;
    // The child whose subtree reaches farthest from d's origin.
    LinkIndex c;
    double first = -1;
    for (const LinkIndex k : kids) {
      const double far = motion.lever(k) + reach[k];
      if (far > first) {
        first = far;
        c = k;
      }
    }
    // From c's origin: d's own capsule, d's other subtrees (their origins
    // and c's are interpolated in d's frame alike) and what lies above d;
    // the cheap terms first, each able to end the walk.
    double up_c = motion.lever(c) + up;
    if (!(std::max(reach[c], up_c) < bound)) break;
    up_c = std::max(up_c, OwnFromChild(skeleton, motion, growth, d, c));
    if (!(up_c < bound)) break;
    bool narrower = true;
    for (const LinkIndex s : kids) {
      if (s == c) continue;
      const double apart =
          Apart(motion.offset(c, 0), motion.offset(c, 1), motion.offset(s, 0), motion.offset(s, 1));
      up_c = std::max(up_c, apart + reach[s]);
      if (!(up_c < bound)) {
        narrower = false;
        break;
      }
    }
    if (!narrower) break;
    d = c;
    bound = std::max(reach[c], up_c);
    up = up_c;
  }
  *radius = bound;
  return d;
}

LinkCapsule GroupBall(const PairMotion& motion, LinkIndex centre, double radius,
                      double tolerance_m) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  LinkCapsule ball;
  ball.a = ball.b = motion.PoseAt(centre, 0.5).p;
  ball.radius =
      radius + tolerance_m + 4 * motion.rounding_slack() + BoxPad(motion.coordinate_scale());
  ball.link = centre;
  return ball;
}

LinkCapsule GroupBallAtMidpoint(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                                LinkIndex centre, double radius, double tolerance_m) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  LinkCapsule ball;
  ball.a = ball.b = 0.5 * (pose0.links[centre].p + pose1.links[centre].p);
  // The products by 0.5 and 8 are exact (short of subnormals, which BoxPad
  // covers, as it covers the sums' rounding and the midpoint's).
  ball.radius = radius + 0.5 * motion.OriginSpeedUpper(centre) + tolerance_m +
                8 * motion.rounding_slack() + BoxPad(motion.coordinate_scale());
  ball.link = centre;
  return ball;
}

LinkCapsule StaticGroupBall(const LinkGroups& groups, const Skeleton& skeleton, PairMotion* motion,
                            const Pose& pose0, const Pose& pose1, LinkIndex root,
                            double tolerance_m, std::vector<double>* stat) {
  SWEPTCCD_CHECK(motion->model() == MotionModel::kArticulated && motion->LinkBegun(root));
  std::vector<double>& r = *stat;
  const LinkIndex* first = groups.begin(root);
  const LinkIndex* last = groups.end(root);
  for (const LinkIndex* m = first + 1; m != last; ++m) r[*m] = 0;
  for (const LinkIndex* m = last - 1; m != first; --m) {  // Children first.
    const LinkIndex j = *m;
    r[j] = std::max(r[j], skeleton.extent(j) + skeleton.link(j).radius);
    const LinkIndex k(skeleton.link(j).parent);
    if (k != root) r[k] = std::max(r[k], motion->lever(j) + r[j]);
  }
  const std::vector<LinkIndex>& kids = groups.children(root);
  SWEPTCCD_CHECK(!kids.empty());
  LinkIndex d = kids[0];
  for (const LinkIndex c : kids) {
    if (motion->lever(c) + r[c] > motion->lever(d) + r[d]) d = c;
  }
  motion->BeginLink(d);
  const Link& own = skeleton.link(root);
  const Eigen::Vector3d& d0 = motion->offset(d, 0);
  const Eigen::Vector3d& d1 = motion->offset(d, 1);
  double radius =
      std::max(Apart(d0, d1, own.a_L, own.a_L), Apart(d0, d1, own.b_L, own.b_L)) + own.radius;
  for (const LinkIndex c : kids) {
    const double apart =
        c == d ? 0.0
               : Apart(pose0.links[c].p, pose1.links[c].p, pose0.links[d].p, pose1.links[d].p);
    radius = std::max(radius, apart + r[c]);
  }
  // The sums' and the unit quaternions' rounding (far below 1e-12 relative).
  radius *= 1.0 + 1e-12;
  return GroupBallAtMidpoint(*motion, pose0, pose1, d, radius, tolerance_m);
}

}  // namespace sweptccd::internal
