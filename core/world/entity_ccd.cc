#include "core/world/entity_ccd.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <unordered_map>
#include <utility>

#include "core/avatar/motion_memo.h"
#include "core/errors.h"
#include "core/geometry/distance.h"
#include "core/geometry/segment_gap.h"
#include "core/query/ccd_query.h"
#include "core/thread_spare.h"
#include "core/world/link_sweep_boxes.h"

namespace sweptccd::world {
namespace {

// Widens a normalised time range by a relative 1e-12 (the rounding of the
// tau -> s mapping), clamped to [0, 1].
void WidenS(double* s0, double* s1) {
  *s0 = std::max(0.0, *s0 - 1e-12);
  *s1 = std::min(1.0, *s1 + 1e-12);
}

Eigen::Vector3d UnitOr(const Eigen::Vector3d& v, const Eigen::Vector3d& fallback) {
  const double n = v.norm();
  return n > 0 ? Eigen::Vector3d(v / n) : fallback;
}

// Another avatar: candidates are its link indices.
class AvatarTarget : public OtherTarget {
 public:
  AvatarTarget(const World& world, int a, int b, double scale, IntervalMotions* shared)
      : world_(world),
        a_(a),
        b_(b),
        e_(world.avatars[b]),
        own_(shared != nullptr
                 ? nullptr
                 : std::make_unique<IntervalMotions>(e_, std::numeric_limits<size_t>::max())),
        motions_(shared != nullptr ? shared : own_.get()) {
    tol_ = std::ldexp((scale >= 0 ? scale : EntityScale(e_)) + 10.0, -22) + 1e-9;
    // A rule can only ignore a link pair of A and B when it names the other
    // avatar (World::IgnoresLinkPair); with none, every link is a root.
    const auto names = [&](int x, int y) {
      return std::any_of(world.rules[x].begin(), world.rules[x].end(),
                         [&](const EntityRule& r) { return r.entity == world.avatars[y].id; });
    };
    filtered_ = names(a, b) || names(b, a);
  }

  void RootCandidatesInto(int link_a, std::vector<int>* out) const override {
    out->clear();
    out->reserve(static_cast<size_t>(e_.skeleton.num_links()));
    for (int j = 0; j < e_.skeleton.num_links(); ++j) {
      if (!filtered_ || !world_.IgnoresLinkPair(a_, link_a, b_, j)) out->push_back(j);
    }
  }

  Aabb PieceBox(const Piece& piece, double tau0, double tau1) const override {
    return GrowPieceBox(piece, tau0, tau1, nullptr);
  }

  // As PieceBox, link by link, stopping as soon as the union meets `box`
  // (B's links not needed are not composed; those composed are kept for
  // Cull, which asks for the same intervals at the root items).
  bool PieceBoxMeets(const Piece& piece, double tau0, double tau1,
                     const Aabb& box_a) const override {
    return box_a.Overlaps(GrowPieceBox(piece, tau0, tau1, &box_a));
  }

  void Cull(const Piece& piece, double tau0, double tau1, const Eigen::Vector3d& a,
            const Eigen::Vector3d& b, double radius_a, double growth_a,
            std::vector<int>* cands) const override {
    MotionMemo& m = MemoOf(piece.k);
    double s0 = piece.SE(tau0), s1 = piece.SE(tau1);
    WidenS(&s0, &s1);
    const double tol = tolerance();
    size_t kept = 0;
    // A box test first: B's capsule box (kept with its swept capsule) apart
    // from A's capsule box grown by A's share of the reach means the
    // segments are farther apart than the reach. The 1 nm and relative 1e-9
    // cover the boxes' rounding (ulps of metre coordinates are ~1e-15 m).
    const double grow_a = (radius_a + growth_a + tol) * (1 + 1e-9) + 1e-9;
    const Aabb box_a = Aabb::OfCapsule(a, b, grow_a);
    std::vector<SweptLink>& links = SweptLinks(piece.k, s0, s1);
    for (int j : *cands) {
      Eigen::Vector3d c1, c2;
      const SweptLink& x = SweptOf(m, s0, s1, j, &links);
      if (!box_a.Overlaps(x.box)) continue;
      const double reach = radius_a + growth_a + e_.skeleton.link(j).radius + x.g + tol;
      // Then a gap on two axes, a lower bound on the distance: past the
      // reach by more than tol (far above the few ulps that the gap and the
      // exact distance below are each off by), the exact test would drop j
      // too. Only what it drops is dropped, so the descent is unchanged.
      if (SegmentGapLowerBound(a, b, x.a, x.b) > reach * (1 + 1e-9) + tol) continue;
      const double d2 = SegmentSegmentDistanceSquared(a, b, x.a, x.b, &c1, &c2);
      if (d2 <= reach * reach * (1 + 1e-9)) (*cands)[kept++] = j;
    }
    cands->resize(kept);
  }

  bool Nearest(const Piece& piece, double tau, int link_a, const Eigen::Vector3d& a,
               const Eigen::Vector3d& b, double radius_a, const std::vector<int>& cands,
               double search, OtherContact* out) const override {
    MotionMemo& m = MemoOf(piece.k);
    const double s = piece.SE(tau);
    bool have = false;
    // Boxes first, as in Cull: apart, the separation is over `search`.
    const Aabb box_a =
        Aabb::OfCapsule(a, b, (radius_a + std::max(search, 0.0)) * (1 + 1e-9) + 1e-9);
    std::vector<InstantLink>& links = InstantLinks(piece.k, s);
    for (int j : cands) {
      Eigen::Vector3d c1, c2;
      const InstantLink& x = InstantOf(m, s, j, &links);
      const Eigen::Vector3d& pa = x.a;
      const Eigen::Vector3d& pb = x.b;
      if (!box_a.Overlaps(x.box)) continue;
      const double d = std::sqrt(SegmentSegmentDistanceSquared(a, b, pa, pb, &c1, &c2));
      const double sep = d - radius_a - e_.skeleton.link(j).radius;
      if (sep > search || (have && sep >= out->separation)) continue;
      have = true;
      out->link = link_a;
      out->other_link = j;
      out->triangle = -1;
      out->tau = tau;
      out->point_link = c1;
      out->point_other = c2;
      out->normal = UnitOr(c1 - c2, Eigen::Vector3d(0, 0, 1));
      out->separation = sep;
    }
    return have;
  }

  double tolerance() const override { return tol_; }

  bool LinkBoxes(const Piece& piece, std::vector<Aabb>* boxes) const override {
    const std::vector<Aabb>& held = motions_->LinkBoxesOf(piece.k);
    boxes->assign(held.begin(), held.end());
    return true;
  }

 private:
  // The union of B's link capsules over the piece's [tau0, tau1], grown
  // link by link; with `until`, it stops at the first link that makes the
  // union meet *until (the rest is not composed).
  Aabb GrowPieceBox(const Piece& piece, double tau0, double tau1, const Aabb* until) const {
    MotionMemo& m = MemoOf(piece.k);
    double s0 = piece.SE(tau0), s1 = piece.SE(tau1);
    WidenS(&s0, &s1);
    Aabb box = Aabb::Empty();
    std::vector<SweptLink>& links = SweptLinks(piece.k, s0, s1);
    for (int j = 0; j < e_.skeleton.num_links(); ++j) {
      const SweptLink& x = SweptOf(m, s0, s1, j, &links);
      box.Grow(Aabb::OfCapsule(x.a, x.b, e_.skeleton.link(j).radius + x.g));
      if (until != nullptr && until->Overlaps(box)) break;
    }
    return box;
  }

  // B's motion over its interval k, with its memo of poses and segments
  // (B's links at one instant share their ancestors' poses).
  MotionMemo& MemoOf(int k) const { return motions_->MemoOf(k); }

  // B's swept capsule of link j over [s0, s1] of its interval k, as
  // PairMotion::SweptCapsule computes it. Every link of A asks for the same
  // intervals (time slicing halves the same pieces), so each is computed
  // once and kept: the same bits, a fraction of the work. The memo is
  // emptied when it holds kMaxSweptKeys intervals (items come in time order,
  // so the intervals asked again are the recent ones).
  struct SweptLink {
    Eigen::Vector3d a, b;
    double g = 0;
    Aabb box;  // Of the capsule (a, b) with the link's radius + g.
    bool computed = false;
  };
  struct SweptKey {
    int k;
    double s0, s1;
    bool operator==(const SweptKey& o) const {  // Bit-exact (-0.0 is not 0.0).
      return k == o.k && std::memcmp(&s0, &o.s0, sizeof s0) == 0 &&
             std::memcmp(&s1, &o.s1, sizeof s1) == 0;
    }
  };
  struct SweptKeyHash {
    size_t operator()(const SweptKey& x) const {
      uint64_t u0, u1;
      std::memcpy(&u0, &x.s0, sizeof u0);
      std::memcpy(&u1, &x.s1, sizeof u1);
      return std::hash<uint64_t>()(u0 * 0x9E3779B97F4A7C15ull ^ (u1 + static_cast<uint64_t>(x.k)));
    }
  };
  static constexpr size_t kMaxSweptKeys = 1024;

  // B's segment of link j at s of its interval k, as PairMotion::SegmentAt
  // computes it, with its capsule's box, kept like the swept capsules: every
  // link of A asks for B's links at the same instants (the window's start
  // for all of them).
  struct InstantLink {
    Eigen::Vector3d a, b;
    Aabb box;  // Of the capsule (a, b) with the link's radius.
    bool computed = false;
  };
  std::vector<InstantLink>& InstantLinks(int k, double s) const {
    if (instants_.size() >= kMaxSweptKeys) instants_.clear();
    std::vector<InstantLink>& links = instants_[SweptKey{k, s, s}];
    if (links.empty()) links.resize(static_cast<size_t>(e_.skeleton.num_links()));
    return links;
  }
  const InstantLink& InstantOf(MotionMemo& m, double s, int j,
                               std::vector<InstantLink>* links) const {
    InstantLink& x = (*links)[static_cast<size_t>(j)];
    if (!x.computed) {
      m.SegmentAt(j, s, &x.a, &x.b);
      x.box = Aabb::OfCapsule(x.a, x.b, e_.skeleton.link(j).radius);
      x.computed = true;
    }
    return x;
  }

  // The memo's entry of the interval [s0, s1] of B's interval k: one look-up
  // per Cull or PieceBox, not one per candidate.
  std::vector<SweptLink>& SweptLinks(int k, double s0, double s1) const {
    if (swept_.size() >= kMaxSweptKeys) swept_.clear();
    std::vector<SweptLink>& links = swept_[SweptKey{k, s0, s1}];
    if (links.empty()) links.resize(static_cast<size_t>(e_.skeleton.num_links()));
    return links;
  }
  // B's swept capsule of link j in `links` (SweptLinks(k, s0, s1)).
  const SweptLink& SweptOf(MotionMemo& m, double s0, double s1, int j,
                           std::vector<SweptLink>* links) const {
    SweptLink& x = (*links)[static_cast<size_t>(j)];
    if (!x.computed) {
      m.SweptCapsule(j, s0, s1, &x.a, &x.b, &x.g);
      x.box = Aabb::OfCapsule(x.a, x.b, e_.skeleton.link(j).radius + x.g);
      x.computed = true;
    }
    return x;
  }

  const World& world_;
  int a_, b_;
  const AvatarEntity& e_;
  // B's motions: the caller's, else own_ (every interval of this answer kept).
  std::unique_ptr<IntervalMotions> own_;
  IntervalMotions* motions_;
  double tol_ = 0;
  bool filtered_ = true;  // Some rule of A or B names the other.
  mutable std::unordered_map<SweptKey, std::vector<SweptLink>, SweptKeyHash> swept_;
  mutable std::unordered_map<SweptKey, std::vector<InstantLink>, SweptKeyHash> instants_;
};

// A tracked object: one candidate (0); its triangles come from its BVH, in
// the object's frame, with A's link taken relative to the object's frame.
class ObjectTarget : public OtherTarget {
 public:
  ObjectTarget(const World& world, int a, int o, double scale)
      : world_(world),
        a_(a),
        o_(o),
        e_(world.objects[o]),
        bvh_(e_.mesh->object(0).bvh),
        rho_(ObjectRadius(bvh_)) {
    if (scale < 0) scale = EntityScale(e_);
    tol_ = e_.mesh->coordinate_tolerance() + std::ldexp(scale + 10.0, -22) + 1e-9;
  }

  void RootCandidatesInto(int link_a, std::vector<int>* out) const override {
    out->clear();
    if (bvh_.num_triangles() == 0 || world_.IgnoresObject(a_, link_a, o_)) return;
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

  bool Nearest(const Piece& piece, double tau, int link_a, const Eigen::Vector3d& a,
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
        out->other_link = -1;
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

 private:
  RigidMotion MotionOf(int k) const {
    const int k1 = std::min<int>(k + 1, static_cast<int>(e_.used.size()) - 1);
    return RigidMotion(e_.used[k], e_.used[k1]);
  }

  const World& world_;
  int a_, o_;
  const ObjectEntity& e_;
  const TriangleBvh& bvh_;
  double rho_ = 0;
  double tol_ = 0;
};

// An item of the descent; its candidates are arena[off, off + len) of the
// answer's candidate arena (both halves of a split share one list).
struct Item {
  double tau0, tau1;
  int link;
  int piece;
  size_t off, len;
};
struct Later {
  bool operator()(const Item& x, const Item& y) const {
    if (x.tau0 != y.tau0) return x.tau0 > y.tau0;
    if (x.link != y.link) return x.link > y.link;
    return x.piece > y.piece;
  }
};

// AnswerOther's arrays, kept per thread between calls (ThreadSpare) so
// that an entry allocates almost nothing (an avatar record asks for 15-31
// of them). Only capacity carries over: every array is cleared or
// overwritten before use.
struct AnswerScratch {
  std::vector<std::vector<int>> roots, cands;  // Lists: at most the links of an entity each.
  std::vector<Aabb> boxes_e, piece_boxes, unions;
  std::vector<Item> queue;
  std::vector<int> arena, work;
};

// This thread's AnswerScratch for one call; what a rare large call left
// past these sizes is freed instead of kept.
class ScratchLease : public ThreadSpare<AnswerScratch> {
 public:
  ~ScratchLease() {
    constexpr size_t kKeptLists = 4096;
    constexpr size_t kKept = size_t{1} << 16;
    AnswerScratch& s = **this;
    FreeIfAbove(&s.roots, kKeptLists);
    FreeIfAbove(&s.cands, kKeptLists);
    FreeIfAbove(&s.boxes_e, kKept);
    FreeIfAbove(&s.piece_boxes, kKept);
    FreeIfAbove(&s.unions, kKept);
    FreeIfAbove(&s.queue, kKept);
    FreeIfAbove(&s.arena, kKept);
    FreeIfAbove(&s.work, kKept);
  }
};

}  // namespace

double Piece::SE(double tau) const {
  if (e_dur <= 0) return 0;
  return std::clamp((tau - e_tau0) / e_dur, 0.0, 1.0);
}

std::vector<Piece> SplitWindow(int64_t utime0, int64_t t_from, int64_t t_to,
                               const std::vector<int64_t>& samples) {
  std::vector<Piece> pieces;
  pieces.reserve(4);  // A pair's window meets a few of E's intervals.
  if (samples.size() == 1) {
    pieces.push_back({static_cast<double>(t_from - utime0), static_cast<double>(t_to - utime0), 0,
                      static_cast<double>(samples[0] - utime0), 0});
    return pieces;
  }
  // The first segment that can overlap: the last sample at or before t_from.
  // (At most the last interval: a window that is the last sample's instant.)
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(samples.size());
  const size_t first = static_cast<size_t>(std::clamp<std::ptrdiff_t>(
      std::upper_bound(samples.begin(), samples.end(), t_from) - samples.begin() - 1, 0, n - 2));
  for (size_t k = first; k + 1 < samples.size() && samples[k] <= t_to; ++k) {
    const int64_t lo = std::max(t_from, samples[k]);
    const int64_t hi = std::min(t_to, samples[k + 1]);
    if (lo > hi) continue;
    if (lo == hi && t_from < t_to) continue;  // A boundary instant of a longer window.
    pieces.push_back({static_cast<double>(lo - utime0), static_cast<double>(hi - utime0),
                      static_cast<int>(k), static_cast<double>(samples[k] - utime0),
                      static_cast<double>(samples[k + 1] - samples[k])});
    if (t_from == t_to) break;
  }
  return pieces;
}

double EntityScale(const AvatarEntity& e) {
  double scale = 0;
  for (const Pose& p : e.used) {
    for (const LinkPose& l : p.links) scale = std::max(scale, l.p.cwiseAbs().maxCoeff());
  }
  for (const Link& l : e.skeleton.links()) scale = std::max({scale, l.a_L.norm(), l.b_L.norm()});
  return scale;
}

double EntityScale(const ObjectEntity& e) {
  double scale = e.mesh->num_objects() > 0 ? e.mesh->object(0).bvh.max_abs_coordinate() : 0.0;
  for (const RigidSample& x : e.used) scale = std::max(scale, x.p.cwiseAbs().maxCoeff());
  return scale;
}

namespace {

// The sample indices [first, last] the pieces use.
std::pair<size_t, size_t> WindowSamples(size_t num_samples, const std::vector<Piece>& pieces) {
  SWEPTCCD_CHECK(!pieces.empty() && num_samples > 0);
  const size_t first = static_cast<size_t>(pieces.front().k);
  const size_t last = std::min(static_cast<size_t>(pieces.back().k) + 1, num_samples - 1);
  SWEPTCCD_CHECK(first <= last);
  return {first, last};
}

}  // namespace

double WindowScale(const AvatarEntity& e, const std::vector<Piece>& pieces) {
  const auto [first, last] = WindowSamples(e.used.size(), pieces);
  double scale = 0;
  for (size_t k = first; k <= last; ++k) {
    for (const LinkPose& l : e.used[k].links) scale = std::max(scale, l.p.cwiseAbs().maxCoeff());
  }
  for (const Link& l : e.skeleton.links()) scale = std::max({scale, l.a_L.norm(), l.b_L.norm()});
  return scale;
}

double WindowScale(const ObjectEntity& e, const std::vector<Piece>& pieces) {
  const auto [first, last] = WindowSamples(e.used.size(), pieces);
  double scale = e.mesh->num_objects() > 0 ? e.mesh->object(0).bvh.max_abs_coordinate() : 0.0;
  for (size_t k = first; k <= last; ++k) scale = std::max(scale, e.used[k].p.cwiseAbs().maxCoeff());
  return scale;
}

namespace {

// Padding of the broad phase's boxes: far above the rounding of a box's own
// arithmetic (ulps of metre coordinates are ~1e-15 m) and above the
// descent's slack (2^-22 of the scale, 16 times less).
double BoxPad(double scale) { return 1e-6 + std::ldexp(scale + 10.0, -18); }

}  // namespace

Aabb AvatarMotionBox(const Skeleton& skeleton, const PairMotion& motion) {
  const double pad = BoxPad(motion.coordinate_scale());
  Aabb box = Aabb::Empty();
  for (int l = 0; l < skeleton.num_links(); ++l) {
    Eigen::Vector3d a, b;
    double g;
    motion.SweptCapsule(l, 0, 1, &a, &b, &g);
    box.Grow(Aabb::OfCapsule(a, b, (skeleton.link(l).radius + g) * (1 + 1e-9) + pad));
  }
  return box;
}

double ObjectRadius(const TriangleBvh& bvh) {
  double rho = 0;
  const Aabb bounds = bvh.bounds();
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? bounds.hi.x() : bounds.lo.x(),
                                 (c & 2) ? bounds.hi.y() : bounds.lo.y(),
                                 (c & 4) ? bounds.hi.z() : bounds.lo.z());
    rho = std::max(rho, corner.norm());
  }
  return rho;
}

Aabb ObjectMotionBox(const RigidSample& x0, const RigidSample& x1, double radius,
                     double mesh_scale) {
  const double scale =
      std::max({mesh_scale, x0.p.cwiseAbs().maxCoeff(), x1.p.cwiseAbs().maxCoeff()});
  return Aabb::OfCapsule(x0.p, x1.p, radius * (1 + 1e-9) + BoxPad(scale));
}

IntervalMotions::Held::Held(const AvatarEntity& e, int k, int k1)
    : motion(e.skeleton, e.used[static_cast<size_t>(k)], e.used[static_cast<size_t>(k1)], e.motion),
      memo(motion, /*max_times=*/64) {}

IntervalMotions::IntervalMotions(const AvatarEntity& entity, size_t max_kept,
                                 std::vector<std::vector<Aabb>> link_boxes)
    : entity_(entity),
      max_kept_(std::max<size_t>(max_kept, 1)),
      given_link_boxes_(std::move(link_boxes)) {}

MotionMemo& IntervalMotions::MemoOf(int k) {
  auto it = held_.find(k);
  if (it != held_.end()) return it->second->memo;
  const int k1 = std::min<int>(k + 1, static_cast<int>(entity_.used.size()) - 1);
  std::unique_ptr<Held> held;
  if (held_.size() >= max_kept_) {
    // Full: the interval farthest from k goes, its memo's memory reused.
    auto far = std::prev(held_.end());
    if (k - held_.begin()->first >= far->first - k) far = held_.begin();
    held = std::move(far->second);
    held_.erase(far);
    // The new motion in the old one's arrays (the same bits, no allocation).
    PairMotion::Storage storage;
    held->motion.Release(&storage);
    held->motion = PairMotion(entity_.skeleton, entity_.used[static_cast<size_t>(k)],
                              entity_.used[static_cast<size_t>(k1)], entity_.motion, &storage);
    held->memo.Rebind(held->motion);
    held->link_boxes.clear();
  } else {
    held = std::make_unique<Held>(entity_, k, k1);
  }
  return held_.emplace(k, std::move(held)).first->second->memo;
}

const std::vector<Aabb>& IntervalMotions::LinkBoxesOf(int k) {
  if (!given_link_boxes_.empty()) {
    SWEPTCCD_CHECK(k >= 0 && static_cast<size_t>(k) < given_link_boxes_.size());
    return given_link_boxes_[static_cast<size_t>(k)];
  }
  MemoOf(k);
  Held& held = *held_.at(k);
  if (held.link_boxes.empty() && entity_.skeleton.num_links() > 0) {
    held.link_boxes = LinkSweepBoxes(entity_.skeleton, held.motion, 0.0);
  }
  return held.link_boxes;
}

std::unique_ptr<OtherTarget> MakeAvatarTarget(const World& world, int a, int b, double scale,
                                              IntervalMotions* motions) {
  return std::make_unique<AvatarTarget>(world, a, b, scale, motions);
}
std::unique_ptr<OtherTarget> MakeObjectTarget(const World& world, int a, int o, double scale) {
  return std::make_unique<ObjectTarget>(world, a, o, scale);
}

namespace {

// s of tau in the pair, rounded down (lo) or up (hi) so that the printed
// normalised time never narrows the certified bracket.
double RoundedS(double tau, double dur, bool up) {
  double s = tau / dur;
  const long double back = static_cast<long double>(s) * dur;
  if (!up && back > tau) s = std::nextafter(s, -HUGE_VAL);
  if (up && back < tau) s = std::nextafter(s, HUGE_VAL);
  return std::clamp(s, 0.0, 1.0);
}

}  // namespace

PrintedBracket PrintBracket(const OtherBracket& b, int64_t utime0, int64_t utime1, int64_t t_from,
                            int64_t t_to) {
  const double dur = static_cast<double>(utime1 - utime0);
  PrintedBracket p;
  const double s_lo = RoundedS(b.tau_lo, dur, false);
  p.s_lo = b.initially_colliding ? static_cast<double>(t_from - utime0) / dur : s_lo;
  p.s_hi = RoundedS(b.tau_hi, dur, true);
  // Inside the window (the rounding of s must not move a bracket end out).
  p.t_lo = b.initially_colliding
               ? static_cast<double>(t_from)
               : std::max(BracketTimeLo(utime0, utime1, s_lo), static_cast<double>(t_from));
  p.t_hi = std::min(BracketTimeHi(utime0, utime1, p.s_hi), static_cast<double>(t_to));
  return p;
}

OtherAnswer AnswerOther(const Skeleton& skeleton_a, const PairMotion& motion_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options) {
  MotionMemo memo_a(motion_a);
  return AnswerOther(skeleton_a, &memo_a, utime0, utime1, pieces, target, options);
}

OtherAnswer AnswerOther(const Skeleton& skeleton_a, MotionMemo* memo, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options, const std::vector<Aabb>* link_boxes_a) {
  const PairMotion& motion_a = memo->motion();
  MotionMemo& memo_a = *memo;
  OtherAnswer answer;
  if (pieces.empty()) return answer;  // No window (SplitWindow of a non-overlapping entity).
  const int num_links = skeleton_a.num_links();
  const double dur = static_cast<double>(utime1 - utime0);
  const double tau_from = pieces.front().tau0, tau_to = pieces.back().tau1;
  const double tol = target.tolerance() + std::ldexp(motion_a.coordinate_scale(), -22) + 1e-9;
  // G2 in printed microseconds: leave room for rounding utime0 + tau.
  const double ulp = std::ldexp(1.0, std::ilogb(std::fabs(static_cast<double>(utime1)) + 1.0) - 50);
  const double eps_us = std::max(options.eps_s * 1e6 - 4 * ulp, 0.5 * options.eps_s * 1e6);
  const double accept = options.delta_m > 4 * tol ? options.delta_m - tol : options.delta_m;
  auto s_of = [&](double tau) { return std::clamp(tau / dur, 0.0, 1.0); };

  // Link-level broad phase (link_sweep_boxes.h): the candidates of A's link
  // l over piece p, cands[l * num_pieces + p], are its roots less E's links
  // whose box over p's sample interval is apart from l's box over the pair
  // by more than the descent's slack on A's side (2 tol, with a relative
  // 1e-8 for the rounding of A's box radius). Every Cull and Nearest of the
  // descent would drop those (their boxes lie inside these), so the
  // descent's answer is unchanged; when none is left anywhere, it is `free`
  // (every item culled, none past the work limit, none touching at the
  // start) with no pose composed.
  const size_t num_pieces = pieces.size();
  ScratchLease lease;
  AnswerScratch& scratch = *lease;
  std::vector<std::vector<int>>& roots = scratch.roots;
  if (roots.size() < static_cast<size_t>(num_links)) roots.resize(num_links);
  for (int l = 0; l < num_links; ++l) target.RootCandidatesInto(l, &roots[l]);
  std::vector<std::vector<int>>& cands = scratch.cands;
  bool use_cands = false;                        // False: the target has no link boxes.
  std::vector<Aabb>& boxes_e = scratch.boxes_e;  // Piece p's link j at p * num_e + j.
  boxes_e.clear();
  size_t num_e = 0;
  bool have = true;
  {
    std::vector<Aabb>& piece_boxes = scratch.piece_boxes;
    piece_boxes.clear();
    for (size_t p = 0; p < num_pieces && have; ++p) {
      have = target.LinkBoxes(pieces[p], &piece_boxes);
      if (p == 0) num_e = piece_boxes.size();
      have = have && piece_boxes.size() == num_e;
      boxes_e.insert(boxes_e.end(), piece_boxes.begin(), piece_boxes.end());
    }
  }
  if (have) {
    std::vector<Aabb> own_boxes;
    if (link_boxes_a == nullptr) {
      own_boxes = LinkSweepBoxes(skeleton_a, motion_a, 0.0);
      link_boxes_a = &own_boxes;
    }
    SWEPTCCD_CHECK(static_cast<int>(link_boxes_a->size()) == num_links);
    const double margin = 2 * tol * (1 + 1e-8);
    std::vector<Aabb>& unions = scratch.unions;
    unions.assign(num_pieces, Aabb::Empty());
    for (size_t p = 0; p < num_pieces; ++p) {
      for (size_t j = 0; j < num_e; ++j) unions[p].Grow(boxes_e[p * num_e + j]);
    }
    // One pass: a link apart from the union of E's boxes over a piece is
    // apart from each of them (each lies inside the union), so its list
    // stays empty without testing them.
    const size_t num_cands = static_cast<size_t>(num_links) * num_pieces;
    if (cands.size() < num_cands) cands.resize(num_cands);
    for (size_t i = 0; i < num_cands; ++i) cands[i].clear();
    use_cands = true;
    int64_t root_items = 0;
    bool any = false;
    for (int l = 0; l < num_links; ++l) {
      if (roots[l].empty()) continue;
      const Aabb& box_a = (*link_boxes_a)[static_cast<size_t>(l)];
      for (size_t p = 0; p < num_pieces; ++p) {
        ++root_items;
        if (BoxesApart(box_a, unions[p], margin)) continue;
        std::vector<int>& c = cands[static_cast<size_t>(l) * num_pieces + p];
        for (int j : roots[l]) {
          if (!BoxesApart(box_a, boxes_e[p * num_e + static_cast<size_t>(j)], margin)) {
            c.push_back(j);
          }
        }
        any = any || !c.empty();
      }
    }
    if (!any && root_items <= options.max_intervals) {
      answer.culled_by_box = true;
      return answer;
    }
  }
  auto cands_of = [&](int l, size_t p) -> const std::vector<int>& {
    return use_cands ? cands[static_cast<size_t>(l) * num_pieces + p] : roots[l];
  };
  std::vector<bool> done(num_links, false);
  std::vector<OtherBracket> brackets;  // In chronological order.
  auto close = [&](const OtherBracket& b) {
    done[b.link] = true;
    brackets.push_back(b);
  };
  // An undecided bracket's witness (SPEC 8: at least one for a contact): the
  // nearest of E's unfiltered candidates to the link at the bracket's start,
  // at any distance, as the environment's undecided brackets have theirs.
  auto close_undecided = [&](OtherBracket b) {
    size_t p = 0;
    while (p + 1 < num_pieces && pieces[p].tau1 < b.tau_lo) ++p;
    Eigen::Vector3d sa, sb;
    memo_a.SegmentAt(b.link, s_of(b.tau_lo), &sa, &sb);
    OtherContact c;
    if (target.Nearest(pieces[p], b.tau_lo, b.link, sa, sb, skeleton_a.link(b.link).radius,
                       roots[b.link], std::numeric_limits<double>::infinity(), &c)) {
      b.has_witness = true;
      b.witness = c;
    }
    close(b);
  };
  auto searching = [&] { return options.per_link || brackets.empty(); };

  // Entity-level broad phase first: A's box over the window against E's.
  // Apart, nothing touches, at the window's start either (the boxes hold
  // the certified swept bounds and the slack), so the answer is the same as
  // with the start tested first, without composing E's links.
  {
    Aabb box_a = Aabb::Empty();
    double s0 = s_of(tau_from), s1 = s_of(tau_to);
    WidenS(&s0, &s1);
    for (int l = 0; l < num_links; ++l) {
      if (roots[l].empty()) continue;
      Eigen::Vector3d a, b;
      double g;
      memo_a.SweptCapsule(l, s0, s1, &a, &b, &g);
      box_a.Grow(Aabb::OfCapsule(a, b, skeleton_a.link(l).radius + g + tol));
    }
    bool overlaps = false;
    for (const Piece& p : pieces)
      overlaps = overlaps || target.PieceBoxMeets(p, p.tau0, p.tau1, box_a);
    if (!overlaps) answer.culled_by_box = true;
    if (!overlaps) std::fill(done.begin(), done.end(), true);
  }

  // Initially colliding: touching at the window's start.
  for (int l = 0; l < num_links && searching() && !answer.culled_by_box; ++l) {
    if (roots[l].empty()) continue;
    Eigen::Vector3d a, b;
    memo_a.SegmentAt(l, s_of(tau_from), &a, &b);
    OtherContact c;
    if (target.Nearest(pieces.front(), tau_from, l, a, b, skeleton_a.link(l).radius, cands_of(l, 0),
                       0.0, &c) &&
        c.separation <= 0) {
      OtherBracket br;
      br.link = l;
      br.tau_lo = tau_from;
      br.tau_hi = std::min(tau_to, tau_from + eps_us);
      br.initially_colliding = true;
      br.has_witness = true;
      br.witness = c;
      close(br);
    }
  }

  // A binary heap under Later, as std::priority_queue keeps it (the same
  // push_heap / pop_heap, so the same order). Candidate lists live in one
  // arena (no allocation per item); `work` holds the popped item's while
  // Cull narrows it. Lists of items no longer queued are dropped when the
  // arena has doubled since it was last compacted.
  std::vector<Item>& queue = scratch.queue;
  std::vector<int>& arena = scratch.arena;
  std::vector<int>& work = scratch.work;
  queue.clear();
  arena.clear();
  size_t compacted = 0;
  auto push = [&](const Item& item) {
    queue.push_back(item);
    std::push_heap(queue.begin(), queue.end(), Later());
  };
  auto store = [&](const std::vector<int>& list) {
    const size_t off = arena.size();
    arena.insert(arena.end(), list.begin(), list.end());
    return off;
  };
  for (int l = 0; l < num_links; ++l) {
    if (done[l] || roots[l].empty()) continue;
    for (int p = 0; p < static_cast<int>(pieces.size()); ++p) {
      const std::vector<int>& c = cands_of(l, static_cast<size_t>(p));
      push(Item{pieces[p].tau0, pieces[p].tau1, l, p, store(c), c.size()});
    }
  }
  while (!queue.empty() && searching()) {
    std::pop_heap(queue.begin(), queue.end(), Later());
    const Item item = queue.back();
    queue.pop_back();
    if (done[item.link]) continue;
    if (++answer.intervals > options.max_intervals) {
      // Out of work: every open link undecided from its earliest item.
      std::vector<double> earliest(num_links, HUGE_VAL);
      earliest[item.link] = item.tau0;
      for (const Item& t : queue) {
        if (!done[t.link]) earliest[t.link] = std::min(earliest[t.link], t.tau0);
      }
      queue.clear();
      std::vector<int> order;
      for (int l = 0; l < num_links; ++l) {
        if (earliest[l] != HUGE_VAL) order.push_back(l);
      }
      std::sort(order.begin(), order.end(),
                [&](int x, int y) { return earliest[x] < earliest[y]; });
      for (int l : order) {
        if (!searching()) break;
        OtherBracket br;
        br.link = l;
        br.tau_lo = earliest[l];
        br.tau_hi = tau_to;
        br.undecided = true;
        close_undecided(br);
      }
      break;
    }
    // No candidate left by the link boxes: Cull would keep none.
    if (item.len == 0) continue;
    work.assign(arena.begin() + static_cast<std::ptrdiff_t>(item.off),
                arena.begin() + static_cast<std::ptrdiff_t>(item.off + item.len));
    const Piece& piece = pieces[item.piece];
    const double r_a = skeleton_a.link(item.link).radius;
    double s0 = s_of(item.tau0), s1 = s_of(item.tau1);
    WidenS(&s0, &s1);
    Eigen::Vector3d a, b;
    double g;
    memo_a.SweptCapsule(item.link, s0, s1, &a, &b, &g);
    target.Cull(piece, item.tau0, item.tau1, a, b, r_a + tol, g, &work);
    if (work.empty()) continue;  // Certified free over the item.
    if (item.tau1 - item.tau0 <= eps_us) {
      OtherContact best, c;
      bool have = false;
      const double mid = 0.5 * (item.tau0 + item.tau1);
      for (double tau : {item.tau0, mid, item.tau1}) {
        Eigen::Vector3d sa, sb;
        memo_a.SegmentAt(item.link, s_of(tau), &sa, &sb);
        if (target.Nearest(piece, tau, item.link, sa, sb, r_a, work, options.delta_m, &c) &&
            (!have || c.separation < best.separation)) {
          best = c;
          have = true;
        }
      }
      if (have && best.separation <= accept) {
        OtherBracket br;
        br.link = item.link;
        br.tau_lo = item.tau0;
        br.tau_hi = item.tau1;
        br.has_witness = true;
        br.witness = best;
        close(br);
        continue;
      }
    }
    const double mid = 0.5 * (item.tau0 + item.tau1);
    if (!(mid > item.tau0 && mid < item.tau1)) {
      OtherBracket br;  // Cannot split further.
      br.link = item.link;
      br.tau_lo = item.tau0;
      br.tau_hi = tau_to;
      br.undecided = true;
      close_undecided(br);
      continue;
    }
    if (arena.size() > std::max<size_t>(2 * compacted, 1 << 16)) {
      std::vector<int> live;  // Only the queued items' lists (order kept).
      for (Item& t : queue) {
        const size_t off = live.size();
        live.insert(live.end(), arena.begin() + static_cast<std::ptrdiff_t>(t.off),
                    arena.begin() + static_cast<std::ptrdiff_t>(t.off + t.len));
        t.off = off;
      }
      arena.swap(live);
      compacted = arena.size();
    }
    const size_t off = store(work);
    push(Item{item.tau0, mid, item.link, item.piece, off, work.size()});
    push(Item{mid, item.tau1, item.link, item.piece, off, work.size()});
  }

  if (!brackets.empty()) {
    answer.contact = true;
    answer.bracket = brackets.front();
    for (const OtherBracket& b : brackets) {
      if (b.tau_lo < answer.bracket.tau_lo) answer.bracket = b;
    }
    if (options.per_link) {
      answer.links = brackets;
      std::sort(answer.links.begin(), answer.links.end(),
                [](const OtherBracket& x, const OtherBracket& y) { return x.link < y.link; });
    }
  }
  return answer;
}

}  // namespace sweptccd::world
