#pragma once
// The avatar: a tree of links, each a line swept sphere (capsule) in its own
// frame (SPEC section 1).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace sweptccd {

struct Link {
  std::string name;
  int parent = -1;        // Index of the parent link, -1 for the root.
  Eigen::Vector3d a_L{0, 0, 0};  // Segment end a, in the link frame L (metres).
  Eigen::Vector3d b_L{0, 0, 0};  // Segment end b, in the link frame L (metres).
  double radius = 0;      // Capsule radius (metres), > 0.
};

/// A validated skeleton: exactly one root, a tree, finite numbers, radius > 0,
/// unique names. Immutable after construction; safe to share between threads.
class Skeleton {
 public:
  Skeleton() = default;

  /// Validates `links` (parents given by index) and builds the tree.
  /// Throws InputError whose message starts with `source` and names the link.
  static Skeleton FromLinks(std::string name, std::vector<Link> links, const std::string& source);

  const std::string& name() const { return name_; }
  int num_links() const { return static_cast<int>(links_.size()); }
  const Link& link(int i) const { return links_[i]; }
  const std::vector<Link>& links() const { return links_; }
  int root() const { return root_; }
  /// max(|a_L|, |b_L|) of link i, rounded up (the upper end of the
  /// interval norm): the farthest point of its segment from its origin.
  double extent(int i) const { return extents_[i]; }
  /// Every link after its parent (root first).
  const std::vector<int>& topological_order() const { return order_; }
  /// Every link after its parent, each subtree contiguous (root first,
  /// children in index order): links near each other in the tree are near
  /// each other in this order.
  const std::vector<int>& depth_first_order() const { return depth_first_; }
  /// Index of the link called `name`, or -1.
  int FindLink(const std::string& name) const;

 private:
  std::string name_;
  std::vector<Link> links_;
  int root_ = -1;
  std::vector<int> order_;
  std::vector<int> depth_first_;
  std::vector<double> extents_;  // By link index.
};

/// Default limit on a skeleton's link count: the engine's cost per pair grows
/// with the link count (docs/DESIGN.md, "Cost bound for large skeletons"), so
/// a file cannot make every query arbitrarily slow. Raised with `--max-links`
/// (query, render) or `max_links` (daemon).
inline constexpr int kDefaultMaxLinks = 256;

/// Parses a SPEC skeleton JSON document. `source` names it in errors (a path).
/// A document with more than `max_links` (>= 1) links is refused before any
/// link is read. Throws InputError naming the source, the link and the
/// problem.
Skeleton ParseSkeletonJson(const std::string& text, const std::string& source,
                           int max_links = kDefaultMaxLinks);

/// Reads and parses a skeleton file of at most kMaxJsonFileBytes
/// (core/bounded_file.h) and at most `max_links` links. Throws InputError
/// ("PATH: problem").
Skeleton LoadSkeletonFile(const std::string& path, int max_links = kDefaultMaxLinks);

/// Serialises a skeleton back to SPEC JSON (used by importers and tests).
std::string SkeletonToJson(const Skeleton& skeleton);

}  // namespace sweptccd
