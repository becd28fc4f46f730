#include "core/query/link_groups.h"

#include <algorithm>

#include "core/errors.h"
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
}

void SubtreeReach(const LinkGroups& groups, const Skeleton& skeleton, const PairMotion& motion,
                  std::vector<double>* reach) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  const std::vector<LinkIndex>& order = groups.preorder();
  reach->assign(order.size(), 0.0);
  for (auto it = order.rbegin(); it != order.rend(); ++it) {  // Children first.
    const LinkIndex j = *it;
    const double own = skeleton.extent(j) + skeleton.link(j).radius + motion.SweepRadius(j, 0, 1);
    double& r = (*reach)[j];
    r = std::max(r, own);
    const int parent = skeleton.link(j).parent;
    if (parent >= 0) {
      double& up = (*reach)[parent];
      up = std::max(up, motion.lever(j) + r);
    }
  }
}

LinkCapsule GroupBall(const Skeleton& skeleton, const PairMotion& motion,
                      const std::vector<double>& reach, LinkIndex root, double tolerance_m) {
  SWEPTCCD_CHECK(motion.model() == MotionModel::kArticulated);
  (void)skeleton;
  LinkCapsule ball;
  ball.a = ball.b = motion.PoseAt(root, 0.5).p;
  ball.radius =
      reach[root] + tolerance_m + 4 * motion.rounding_slack() + BoxPad(motion.coordinate_scale());
  ball.link = root;
  return ball;
}

}  // namespace sweptccd::internal
