#include "core/world/avatar_target.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "core/avatar/motion_memo.h"
#include "core/geometry/distance.h"
#include "core/geometry/rounding_slack.h"
#include "core/geometry/segment_gap.h"

namespace sweptccd::world {
namespace {

// Another avatar: candidates are its link indices.
class AvatarTarget : public OtherTarget {
 public:
  AvatarTarget(const FilterSide& a, const AvatarWindow& b, double scale, IntervalMotions* shared)
      : a_(a),
        e_(b),
        own_(shared != nullptr
                 ? nullptr
                 : std::make_unique<IntervalMotions>(e_, std::numeric_limits<size_t>::max())),
        motions_(shared != nullptr ? shared : own_.get()) {
    tol_ = EntitySlack(scale >= 0 ? scale : EntityScale(e_));
    // A rule can only ignore a link pair of A and B when it names the other
    // avatar (IgnoresLinkPair); with none, every link is a root.
    filtered_ = NamesEntity(a_, e_.who.id) || NamesEntity(e_.who, a_.id);
  }

  void RootCandidatesInto(LinkIndex link_a, std::vector<int>* out) const override {
    out->clear();
    out->reserve(static_cast<size_t>(e_.skeleton.num_links()));
    for (int j = 0; j < e_.skeleton.num_links(); ++j) {
      if (!filtered_ || !IgnoresLinkPair(a_, link_a, e_.who, LinkIndex(j))) out->push_back(j);
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
      const SweptLink& x = SweptOf(m, s0, s1, LinkIndex(j), &links);
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

  bool Nearest(const Piece& piece, double tau, LinkIndex link_a, const Eigen::Vector3d& a,
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
      const InstantLink& x = InstantOf(m, s, LinkIndex(j), &links);
      const Eigen::Vector3d& pa = x.a;
      const Eigen::Vector3d& pb = x.b;
      if (!box_a.Overlaps(x.box)) continue;
      const double d = std::sqrt(SegmentSegmentDistanceSquared(a, b, pa, pb, &c1, &c2));
      const double sep = d - radius_a - e_.skeleton.link(j).radius;
      if (sep > search || (have && sep >= out->separation)) continue;
      have = true;
      out->link = link_a;
      out->other_link = LinkIndex(j);
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

  bool NearLinkBoxes(const Piece& piece, double margin, std::vector<Aabb>* boxes) const override {
    const std::vector<Aabb>& held = motions_->NearLinkBoxesOf(piece.k, margin);
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
    for (LinkIndex j(0); j < e_.skeleton.num_links(); ++j) {
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
  const InstantLink& InstantOf(MotionMemo& m, double s, LinkIndex j,
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
  const SweptLink& SweptOf(MotionMemo& m, double s0, double s1, LinkIndex j,
                           std::vector<SweptLink>* links) const {
    SweptLink& x = (*links)[static_cast<size_t>(j)];
    if (!x.computed) {
      m.SweptCapsule(j, s0, s1, &x.a, &x.b, &x.g);
      x.box = Aabb::OfCapsule(x.a, x.b, e_.skeleton.link(j).radius + x.g);
      x.computed = true;
    }
    return x;
  }

  FilterSide a_;
  AvatarWindow e_;
  // B's motions: the caller's, else own_ (every interval of this answer kept).
  std::unique_ptr<IntervalMotions> own_;
  IntervalMotions* motions_;
  double tol_ = 0;
  bool filtered_ = true;  // Some rule of A or B names the other.
  mutable std::unordered_map<SweptKey, std::vector<SweptLink>, SweptKeyHash> swept_;
  mutable std::unordered_map<SweptKey, std::vector<InstantLink>, SweptKeyHash> instants_;
};

}  // namespace

std::unique_ptr<OtherTarget> MakeAvatarTarget(const FilterSide& a, const AvatarWindow& b,
                                              double scale, IntervalMotions* motions) {
  return std::make_unique<AvatarTarget>(a, b, scale, motions);
}

}  // namespace sweptccd::world
