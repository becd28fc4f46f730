#include "core/avatar/motion.h"

#include <cmath>
#include <limits>

#include "core/errors.h"
#include "core/geometry/interval.h"

namespace sweptccd {

std::optional<MotionModel> ParseMotionModel(const std::string& text) {
  if (text == "articulated") return MotionModel::kArticulated;
  if (text == "independent") return MotionModel::kIndependent;
  return std::nullopt;
}

const char* MotionModelName(MotionModel model) {
  return model == MotionModel::kArticulated ? "articulated" : "independent";
}

namespace {

// Below this 4D angle slerp falls back to normalised lerp; the difference
// between the two is O(angle^3), far below a nanometre for links of metres.
constexpr double kNlerpAngle = 1e-6;

double QuatAngle4D(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1) {
  // For unit vectors u, v: |u - v| = 2 sin(a/2), |u + v| = 2 cos(a/2). The
  // atan2 form is accurate for all angles, unlike acos(dot).
  return 2.0 * std::atan2((q1.coeffs() - q0.coeffs()).norm(), (q1.coeffs() + q0.coeffs()).norm());
}

Eigen::Quaterniond SlerpPrepared(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1,
                                 double half_angle, double s) {
  Eigen::Vector4d v;
  if (half_angle < kNlerpAngle) {
    v = (1 - s) * q0.coeffs() + s * q1.coeffs();
  } else {
    const double inv = 1.0 / std::sin(half_angle);
    v = std::sin((1 - s) * half_angle) * inv * q0.coeffs() +
        std::sin(s * half_angle) * inv * q1.coeffs();
  }
  Eigen::Quaterniond q;
  q.coeffs() = v / v.norm();
  return q;
}

Eigen::Quaterniond ShortestArcTarget(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1) {
  if (internal::DotSign(q0.coeffs().data(), q1.coeffs().data()) < 0) {
    Eigen::Quaterniond n;
    n.coeffs() = -q1.coeffs();
    return n;
  }
  return q1;
}

// The upper end of the interval norm Sqrt(Sqr(x) + Sqr(y) + Sqr(z)), bit for
// bit, without its lower end (interval.h, NormUpper): every bound below reads
// only the upper end of a norm.
double NormHi(const Eigen::Vector3d& v) { return NormUpper(v.x(), v.y(), v.z()); }
// max(NormHi(u), NormHi(v)), bit for bit, with one square root.
double MaxNormHi(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  return NormUpperOfSum(
      std::max(SumOfSquaresUpper(u.x(), u.y(), u.z()), SumOfSquaresUpper(v.x(), v.y(), v.z())));
}

}  // namespace

namespace internal {

namespace {

// a + b = s + e exactly (Knuth's two-sum; no branch, any order of magnitude).
void TwoSum(double a, double b, double* s, double* e) {
  *s = a + b;
  const double bv = *s - a;
  const double av = *s - bv;
  *e = (a - av) + (b - bv);
}

// a * b = p + e exactly (Dekker's product with Veltkamp's split), for
// products and halves clear of overflow and underflow.
void TwoProduct(double a, double b, double* p, double* e) {
  constexpr double kSplit = 134217729.0;  // 2^27 + 1.
  auto split = [](double x, double* hi, double* lo) {
    const double c = kSplit * x;
    *hi = c - (c - x);
    *lo = x - *hi;
  };
  double ah, al, bh, bl;
  split(a, &ah, &al);
  split(b, &bh, &bl);
  *p = a * b;
  *e = ((ah * bh - *p) + ah * bl + al * bh) + al * bl;
}

}  // namespace

int DotSign(const double a[4], const double b[4]) {
  const double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  // The sum's rounding is below 5e-16 for unit vectors: past 1e-12 its sign
  // is the exact one.
  if (std::fabs(d) > 1e-12) return d > 0 ? 1 : -1;
  // Near 0 (a turn of 180 degrees), exactly: the eight parts of the four
  // products summed into a nonoverlapping expansion (Shewchuk's
  // Grow-Expansion), whose largest nonzero part has the sum's sign.
  double expansion[8];
  int n = 0;
  auto grow = [&](double x) {
    double q = x;
    for (int i = 0; i < n; ++i) {
      double h;
      TwoSum(q, expansion[i], &q, &h);
      expansion[i] = h;
    }
    expansion[n++] = q;
  };
  for (int k = 0; k < 4; ++k) {
    double p, e;
    TwoProduct(a[k], b[k], &p, &e);
    grow(e);
    grow(p);
  }
  for (int i = n - 1; i >= 0; --i) {
    if (expansion[i] != 0) return expansion[i] > 0 ? 1 : -1;
  }
  return 0;
}

// Each interval operation's upper end, for the operands met here: sums add
// upper ends; in every product both operands' upper ends are >= 0 and >= the
// magnitude of their lower ends (a lower end is only below 0, by one step,
// where the value is 0), so the greatest of the four end products is the
// product of the upper ends (ties differ at most in the sign of a zero,
// which StepUp treats alike). Sqr's upper end is the square of the upper end
// for the same reason. All of that holds while every step is finite; a
// result that is not (an overflow on the way: inf, or inf * 0) is computed
// again with the intervals.
namespace {
double Up(double x) { return Interval::StepUp(x, 1); }
bool Finite(double x) { return x <= std::numeric_limits<double>::max(); }  // NaN: false.
}  // namespace

double FirstOrderGrowth(double speed, double angular, double extent, double slack, double s0,
                        double s1) {
  const double half_width = Up(Up(s1 - s0) * 0.5);
  const double speed_all = Up(speed + Up(angular * extent));
  const double growth = Up(Up(speed_all * half_width) + slack);
  if (Finite(growth)) return growth;
  const Interval interval_speed = Interval(speed) + Interval(angular) * Interval(extent);
  return (interval_speed * ((Interval(s1) - Interval(s0)) * Interval(0.5)) + Interval(slack)).hi();
}

double SecondOrderGrowth(double chord, double accel, double angular_accel, double angular,
                         double extent, double slack, double s0, double s1) {
  const double acc = Up(accel + Up(Up(angular_accel + Up(angular * angular)) * extent));
  const double width = Up(s1 - s0);
  const double curve = Up(Up(0.25 * Up(width * width)) * acc);
  const double growth = Up(Up(Up(chord * 0.5) + curve) + Up(4.0 * slack));
  if (Finite(growth)) return growth;
  const Interval w(angular);
  const Interval interval_acc =
      Interval(accel) + (Interval(angular_accel) + w * w) * Interval(extent);
  const Interval interval_width = Interval(s1) - Interval(s0);
  return (Interval(chord) * Interval(0.5) + Interval(0.25) * Sqr(interval_width) * interval_acc +
          Interval(4.0) * Interval(slack))
      .hi();
}

LinkBounds LinkBoundsByIntervals(double half_angle, double own_speed_hi, double lever_hi,
                                 const LinkBounds* parent) {
  // Slerp turns at the constant rate 2 * half_angle; the nlerp fallback
  // below kNlerpAngle turns at most (1 + 1e-12) times that: 2 * half_angle,
  // widened for the rounding of atan2 and the nlerp fallback.
  const Interval own_angular =
      Interval(2.0) * Interval::Outward(half_angle, half_angle, 8) * Interval(1.0, 1.0 + 1e-12);
  // Only the upper end of |p1 - p0| reaches a bound: sums' upper ends add
  // upper ends, and its one product, with 2 w_k (upper end >= |lower end|),
  // peaks at the two upper ends whatever its lower end. So the point at the
  // upper end gives the same bits as the interval norm (and so for |c|).
  const Interval own_speed(own_speed_hi);
  LinkBounds out;
  if (parent == nullptr) {
    // Linear position, and slerp turns about a fixed world axis: no
    // acceleration at all.
    out.angular = own_angular.hi();
    out.speed = own_speed.hi();
    return out;
  }
  // Composition adds angular velocities, and the position of a child
  // p_k + R_k c moves at most |p_k'| + |w_k| |c| + |c'|.
  const Interval lever(lever_hi);
  const Interval wk(parent->angular);
  out.angular = (wk + own_angular).hi();
  out.speed = (Interval(parent->speed) + wk * lever + own_speed).hi();
  // The relative slerp turns at a constant rate about an axis fixed in the
  // parent frame, so w_i = w_k + R_k u with |u| = own angle and
  // w_i' = w_k' + w_k x (R_k u). For p_i = p_k + R_k c(s), c linear:
  // p_i'' = p_k'' + w_k' x R_k c + w_k x (w_k x R_k c) + 2 w_k x R_k c'.
  out.angular_accel = (Interval(parent->angular_accel) + wk * own_angular).hi();
  out.accel = (Interval(parent->accel) + Interval(parent->angular_accel) * lever + wk * wk * lever +
               Interval(2.0) * wk * own_speed)
                  .hi();
  return out;
}

bool LinkBoundsByUpperEnds(double half_angle, double own_speed, double lever,
                           const LinkBounds* parent, LinkBounds* out) {
  const double own_angular = Up(Up(2.0 * Interval::StepUp(half_angle, 8)) * (1.0 + 1e-12));
  LinkBounds b;
  if (parent == nullptr) {
    b.angular = own_angular;
    b.speed = own_speed;
  } else {
    const double wk = parent->angular;
    b.angular = Up(wk + own_angular);
    b.speed = Up(Up(parent->speed + Up(wk * lever)) + own_speed);
    b.angular_accel = Up(parent->angular_accel + Up(wk * own_angular));
    b.accel =
        Up(Up(Up(parent->accel + Up(parent->angular_accel * lever)) + Up(Up(wk * wk) * lever)) +
           Up(Up(2.0 * wk) * own_speed));
  }
  if (!Finite(b.angular) || !Finite(b.speed) || !Finite(b.accel) || !Finite(b.angular_accel)) {
    return false;
  }
  *out = b;
  return true;
}

namespace {
// FirstOrderBoundsUpper's and HalfAngleUpper's bodies, inlined into
// PairMotion::Build's loop over the links (a call per link and per bound
// cost about a tenth of the quiet 81-link query's motion; issue 31).
[[gnu::always_inline]] inline void FirstOrderBoundsUpperInline(double half_angle, double own_speed,
                                                               double lever,
                                                               const LinkBounds* parent,
                                                               double* speed, double* angular) {
  const double own_angular = Up(Up(2.0 * Interval::StepUp(half_angle, 8)) * (1.0 + 1e-12));
  double w = own_angular, v = own_speed;
  if (parent != nullptr) {
    const double wk = parent->angular;
    w = Up(wk + own_angular);
    v = Up(Up(parent->speed + Up(wk * lever)) + own_speed);
  }
  const double inf = std::numeric_limits<double>::infinity();
  const bool finite = Finite(w) && Finite(v);
  *speed = finite ? v : inf;
  *angular = finite ? w : inf;
}

[[gnu::always_inline]] inline double HalfAngleUpperInline(const Eigen::Quaterniond& a,
                                                          const Eigen::Quaterniond& b) {
  const Eigen::Vector4d& u = a.coeffs();
  const Eigen::Vector4d& v = b.coeffs();
  const double uu = u.squaredNorm(), vv = v.squaredNorm();
  if (!(std::fabs(uu - 1) <= 1e-9 && std::fabs(vv - 1) <= 1e-9)) return kMaxHalfAngle;
  const double t = std::fabs(u.dot(v)) / std::sqrt(uu * vv) - 1e-14;
  if (!(t > 0)) return kMaxHalfAngle;
  const double bound = Up(Up(2.0 * std::sqrt(std::max(0.0, (1 - t) / (1 + t)))) * (1.0 + 1e-12));
  return std::min(kMaxHalfAngle, Up(bound + 1e-12));
}
}  // namespace

void FirstOrderBoundsUpper(double half_angle, double own_speed, double lever,
                           const LinkBounds* parent, double* speed, double* angular) {
  FirstOrderBoundsUpperInline(half_angle, own_speed, lever, parent, speed, angular);
}

double HalfAngleUpper(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return HalfAngleUpperInline(a, b);
}

// FirstOrderGrowth(speed, angular, extent, slack, 0, 1), bit for bit: the
// same steps, with its half width Up(Up(1 - 0) * 0.5) a constant (PairMotion::
// PairGrowthUpper runs for every link of every quiet query; issue 31).
[[gnu::always_inline]] inline double FirstOrderGrowthOverPairInline(double speed, double angular,
                                                                    double extent, double slack) {
  // Up(1) = 1 + 2^-52; times 0.5 exactly 2^-1 + 2^-53; one step up.
  constexpr double kHalfWidth = 0x1.0000000000002p-1;
  const double speed_all = Up(speed + Up(angular * extent));
  const double growth = Up(Up(speed_all * kHalfWidth) + slack);
  if (Finite(growth)) return growth;
  return FirstOrderGrowth(speed, angular, extent, slack, 0.0, 1.0);  // The interval fallback.
}

double FirstOrderGrowthOverPair(double speed, double angular, double extent, double slack) {
  return FirstOrderGrowthOverPairInline(speed, angular, extent, slack);
}

}  // namespace internal

Eigen::Quaterniond Slerp(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1, double s) {
  const Eigen::Quaterniond t = ShortestArcTarget(q0, q1);
  return SlerpPrepared(q0, t, QuatAngle4D(q0, t), s);
}

double SlerpAngle(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1) {
  return 2.0 * QuatAngle4D(q0, ShortestArcTarget(q0, q1));
}

PairMotion::PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1,
                       MotionModel model)
    : PairMotion(skeleton, pose0, pose1, model, nullptr) {}

PairMotion::PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1,
                       MotionModel model, Storage* storage)
    : PairMotion(skeleton, pose0, pose1, model, storage, Ends::kAll) {}

PairMotion::PairMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1,
                       MotionModel model, Storage* storage, Ends ends,
                       const std::vector<char>* deferred)
    : model_(model) {
  if (storage != nullptr) {
    links_ = std::move(storage->links);
    order_ = std::move(storage->order);
    poses_at_ends_ = std::move(storage->poses);
    segments_at_ends_ = std::move(storage->segments);
  }
  order_.clear();
  for (int i : skeleton.topological_order()) order_.push_back(LinkIndex(i));
  SWEPTCCD_CHECK(deferred == nullptr ||
                 (ends == Ends::kOnDemand && model == MotionModel::kArticulated &&
                  static_cast<int>(deferred->size()) == skeleton.num_links()));
  Build(skeleton, pose0, pose1, ends, deferred);
}

void PairMotion::Release(Storage* storage) {
  storage->links = std::move(links_);
  storage->order = std::move(order_);
  storage->poses = std::move(poses_at_ends_);
  storage->segments = std::move(segments_at_ends_);
  links_.clear();
  order_.clear();
  poses_at_ends_.clear();
  segments_at_ends_.clear();
}

// Inlined into Build's loop (kAll: every link, pair after pair) and
// CompleteMotion: a call per link cost more than the checks it replaced.
[[gnu::always_inline]] inline void PairMotion::FinishMotion(LinkMotion* motion) {
  LinkMotion& m = *motion;
  if (m.parent.is_valid()) {
    m.q0 = m.q0.normalized();
    m.q1 = m.q1.normalized();
    // The numbers SPEC 3's sign is decided on, and the slerp then uses.
    FlushTinyComponents(&m.q0);
    FlushTinyComponents(&m.q1);
  }
  m.q1 = ShortestArcTarget(m.q0, m.q1);
  m.half_angle = QuatAngle4D(m.q0, m.q1);
  m.sin_half = m.inv_sin_half = m.sin_quarter = 0;
  if (m.half_angle >= kNlerpAngle) {
    m.sin_half = std::sin(m.half_angle);
    m.inv_sin_half = 1.0 / m.sin_half;
    m.sin_quarter = std::sin(0.5 * m.half_angle);
  }
  const internal::LinkBounds* parent = !m.parent.is_valid() ? nullptr : &links_[m.parent].bounds;
  m.own_speed = NormHi(m.p1 - m.p0);
  m.lever = parent == nullptr ? 0.0 : MaxNormHi(m.p0, m.p1);
  if (!internal::LinkBoundsByUpperEnds(m.half_angle, m.own_speed, m.lever, parent, &m.bounds)) {
    m.bounds = internal::LinkBoundsByIntervals(m.half_angle, m.own_speed, m.lever, parent);
  }
  m.motion_ready = true;
}

[[gnu::always_inline]] inline void PairMotion::StartChild(LinkMotion* m, const LinkPose& x0,
                                                          const LinkPose& x1, const LinkPose& k0,
                                                          const LinkPose& k1) const {
  m->p0 = k0.q.toRotationMatrix().transpose() * (x0.p - k0.p);
  m->p1 = k1.q.toRotationMatrix().transpose() * (x1.p - k1.p);
  m->q0 = k0.q.conjugate() * x0.q;  // FinishMotion normalises them.
  m->q1 = k1.q.conjugate() * x1.q;
}

// Upper bounds of NormHi and MaxNormHi (FinishMotion's): a norm rounded to
// nearest is within 4 ulps of the exact one, theirs within 20 ulps above it
// (1e-12 relative is far more); where squares underflow, their steps up from
// 0 add at most 8 x 2^-1074 under the root, 7e-162 above it (the 1e-150).
constexpr double kWide = 1.0 + 1e-12;

[[gnu::always_inline]] inline void PairMotion::BoundChild(LinkMotion* motion) const {
  LinkMotion& m = *motion;
  m.motion_ready = false;
  m.own_speed = std::sqrt((m.p1 - m.p0).squaredNorm()) * kWide + 1e-150;
  m.lever = std::sqrt(std::max(m.p0.squaredNorm(), m.p1.squaredNorm())) * kWide + 1e-150;
  const internal::LinkBounds& parent = links_[m.parent].bounds;
  internal::FirstOrderBoundsUpperInline(internal::HalfAngleUpperInline(m.q0, m.q1), m.own_speed,
                                        m.lever, &parent, &m.bounds.speed, &m.bounds.angular);
  m.bounds.accel = m.bounds.angular_accel = std::numeric_limits<double>::quiet_NaN();
}

void PairMotion::BeginLink(LinkIndex link) {
  LinkMotion& m = links_[link];
  if (m.begun) return;
  SWEPTCCD_CHECK(m.parent.is_valid() && links_[m.parent].begun && pose0_ != nullptr);
  StartChild(&m, pose0_->links[link], pose1_->links[link], pose0_->links[m.parent],
             pose1_->links[m.parent]);
  BoundChild(&m);
  m.begun = true;
}

void PairMotion::CheckLinkBegun(LinkIndex link) const { SWEPTCCD_CHECK(links_[link].begun); }

void PairMotion::Build(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, Ends ends,
                       const std::vector<char>* deferred) {
  const int n = skeleton.num_links();
  SWEPTCCD_CHECK(static_cast<int>(pose0.links.size()) == n);
  SWEPTCCD_CHECK(static_cast<int>(pose1.links.size()) == n);
  links_.resize(n);
  double scale = 0;
  for (int i = 0; i < n; ++i) {
    const Link& link = skeleton.link(i);
    LinkMotion& m = links_[i];
    // Every field is written below: the array may hold an earlier motion.
    m.parent = LinkIndex();
    m.depth = 1;
    m.a_L = link.a_L;
    m.b_L = link.b_L;
    m.extent = skeleton.extent(i);  // Hull(Norm(a), Norm(b)).hi()
    m.begun = true;
    const LinkPose& x0 = pose0.links[i];
    const LinkPose& x1 = pose1.links[i];
    scale = std::max({scale, x0.p.cwiseAbs().maxCoeff(), x1.p.cwiseAbs().maxCoeff(), m.extent});
    if (model_ == MotionModel::kArticulated && link.parent >= 0) {
      const LinkPose& k0 = pose0.links[link.parent];
      const LinkPose& k1 = pose1.links[link.parent];
      m.parent = LinkIndex(link.parent);
      // The offsets' scale from the world positions (|c| = |p - k|, never
      // below a coordinate of c but for the rounding the 1e-12 covers), so
      // that it does not depend on which links are deferred.
      const double lever =
          std::sqrt(std::max((x0.p - k0.p).squaredNorm(), (x1.p - k1.p).squaredNorm())) * kWide +
          1e-150;
      scale = std::max(scale, lever);
      if (deferred != nullptr && (*deferred)[i] != 0) {
        m.begun = false;
        m.lever = lever;
        continue;
      }
      StartChild(&m, x0, x1, k0, k1);
    } else {
      m.p0 = x0.p;
      m.p1 = x1.p;
      m.q0 = x0.q;
      m.q1 = x1.q;
    }
  }
  pose0_ = deferred != nullptr ? &pose0 : nullptr;
  pose1_ = deferred != nullptr ? &pose1 : nullptr;
  // Speed bounds, parents first (internal::LinkBoundsByIntervals). kOnDemand
  // finishes only the links that move on their own; the others get upper
  // bounds of their lever, own speed, speed and angular speed
  // (PairGrowthUpper), parents first, from their parent's bounds (exact or
  // upper) and HalfAngleUpper. Chain depth, parents first (linear time).
  all_ready_ = ends == Ends::kAll;
  int depth = 1;
  for (LinkIndex i : order_) {
    LinkMotion& m = links_[i];
    if (m.parent.is_valid()) m.depth = links_[m.parent].depth + 1;
    depth = std::max(depth, m.depth);
    m.ends_ready = all_ready_;
    if (all_ready_ || !m.parent.is_valid()) {
      FinishMotion(&m);
      continue;
    }
    if (!m.begun) {  // Deferred: infinite bounds until BeginLink.
      m.motion_ready = false;
      m.own_speed = std::numeric_limits<double>::infinity();
      m.bounds.speed = m.bounds.angular = std::numeric_limits<double>::infinity();
      m.bounds.accel = m.bounds.angular_accel = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    BoundChild(&m);
  }
  // Slack for the rounding of SegmentAt: each composition step loses a few
  // ulps of the magnitudes involved; 1e-10 relative is many orders above that.
  rounding_slack_ = 1e-10 * (1.0 + scale * depth);
  coordinate_scale_ = scale;
  // Linear in the link count; PoseAt composes O(depth) per call otherwise,
  // quadratic over a chain (9.2 s per pair for 10,000 links). For
  // `independent` a pose is its own slerp; the look-up still saves it.
  poses_at_ends_.resize(3 * static_cast<size_t>(n));
  segments_at_ends_.resize(6 * static_cast<size_t>(n));
  if (ends == Ends::kOnDemand) return;  // CompleteEnds, link by link.
  PosesAtInto(0.0, &poses_at_ends_[0]);
  PosesAtInto(0.5, &poses_at_ends_[n]);
  PosesAtInto(1.0, &poses_at_ends_[2 * n]);
  for (int k = 0; k < 3; ++k) {
    for (LinkIndex i(0); i < n; ++i) {
      SegmentOfPose(i, poses_at_ends_[k * n + i], &segments_at_ends_[6 * i + 2 * k],
                    &segments_at_ends_[6 * i + 2 * k + 1]);
    }
  }
}

void PairMotion::CompleteMotion(LinkIndex link) {
  LinkMotion& m = links_[link];
  if (m.motion_ready) return;
  SWEPTCCD_CHECK(m.begun && (!m.parent.is_valid() || links_[m.parent].motion_ready));
  FinishMotion(&m);
}

[[gnu::always_inline]] inline double PairMotion::GrowthUpper(const LinkMotion& m) const {
  if (!m.begun) return std::numeric_limits<double>::infinity();
  const double g = internal::FirstOrderGrowthOverPairInline(m.bounds.speed, m.bounds.angular,
                                                            m.extent, rounding_slack_);
  if (all_ready_ || m.motion_ready) return g;  // SweepRadius(link, 0, 1).
  // An upper bound's growth: the same monotone steps as the exact one's;
  // past 1e300 (an overflow on the way) infinite rather than the interval
  // fallback's, which need not exceed the exact bound's rounded steps.
  return g <= 1e300 ? g : std::numeric_limits<double>::infinity();
}

double PairMotion::PairGrowthUpper(LinkIndex link) const { return GrowthUpper(links_[link]); }

void PairMotion::PairGrowthUppers(std::vector<double>* out) const {
  out->resize(links_.size());
  for (size_t i = 0; i < links_.size(); ++i) (*out)[i] = GrowthUpper(links_[i]);
}

// One link's share of Build's PosesAtInto at 0, 0.5 and 1 and of its
// segment loop: the same operations, so the same bits.
void PairMotion::CompleteEnds(LinkIndex link) {
  LinkMotion& m = links_[link];
  if (m.ends_ready) return;
  SWEPTCCD_CHECK(!m.parent.is_valid() || links_[m.parent].ends_ready);
  CompleteMotion(link);
  const size_t n = links_.size();
  for (int k = 0; k < 3; ++k) {
    const double s = k == 0 ? 0.0 : k == 1 ? 0.5 : 1.0;
    LinkPose& X = poses_at_ends_[k * n + link];
    X = Compose(m, s, !m.parent.is_valid() ? LinkPose() : poses_at_ends_[k * n + m.parent]);
    SegmentOfPose(link, X, &segments_at_ends_[6 * link + 2 * k],
                  &segments_at_ends_[6 * link + 2 * k + 1]);
  }
  m.ends_ready = true;
}

void PairMotion::CheckLinkEndsReady(LinkIndex link) const {
  SWEPTCCD_CHECK(links_[link].ends_ready);
}

void PairMotion::CheckLinkMotionReady(LinkIndex link) const {
  SWEPTCCD_CHECK(links_[link].motion_ready);
}

// SlerpPrepared(m.q0, m.q1, m.half_angle, s), bit for bit, with the sines
// computed at construction where s allows: sin(half_angle) always (and its
// inverse), both sines at s = 0, 0.5 and 1. At s = 0 (and s = 1) the other
// argument is s * half_angle = +-0 (or (1 - s) * half_angle = +0), whose sine
// is itself.
Eigen::Quaterniond PairMotion::LocalRotation(const LinkMotion& m, double s) const {
  if (m.half_angle < kNlerpAngle) return SlerpPrepared(m.q0, m.q1, m.half_angle, s);
  double sin_a, sin_b;  // sin((1 - s) * half_angle), sin(s * half_angle).
  if (s == 0.0) {
    sin_a = m.sin_half;  // (1 - s) * half_angle == half_angle.
    sin_b = s * m.half_angle;
  } else if (s == 1.0) {
    sin_a = (1 - s) * m.half_angle;
    sin_b = m.sin_half;  // s * half_angle == half_angle.
  } else if (s == 0.5) {
    sin_a = m.sin_quarter;  // (1 - s) * half_angle == s * half_angle == half_angle / 2.
    sin_b = m.sin_quarter;
  } else {
    sin_a = std::sin((1 - s) * m.half_angle);
    sin_b = std::sin(s * m.half_angle);
  }
  const double inv = m.inv_sin_half;
  const Eigen::Vector4d v = sin_a * inv * m.q0.coeffs() + sin_b * inv * m.q1.coeffs();
  Eigen::Quaterniond q;
  q.coeffs() = v / v.norm();
  return q;
}

LinkPose PairMotion::Compose(const LinkMotion& m, double s, const LinkPose& X_WP) const {
  const Eigen::Vector3d c = (1 - s) * m.p0 + s * m.p1;
  const Eigen::Quaterniond r = LocalRotation(m, s);
  LinkPose out;
  if (!m.parent.is_valid()) {
    out.p = c;
    out.q = r;
  } else {
    out.q = (X_WP.q * r).normalized();
    out.p = X_WP.p + X_WP.q * c;
  }
  return out;
}

void PairMotion::PosesAt(double s, std::vector<LinkPose>* X_WL) const {
  X_WL->resize(links_.size());
  PosesAtInto(s, X_WL->data());
}

void PairMotion::PosesAtInto(double s, LinkPose* X_WL) const {
  for (LinkIndex i : order_) {
    CheckMotionReady(i);
    const LinkMotion& m = links_[i];
    X_WL[i] = Compose(m, s, !m.parent.is_valid() ? LinkPose() : X_WL[m.parent]);
  }
}

LinkPose PairMotion::PoseFromParent(LinkIndex link, double s, const LinkPose& X_WP) const {
  if (!poses_at_ends_.empty() && (s == 0.0 || s == 0.5 || s == 1.0)) {  // PoseAt's look-ups.
    CheckEndsReady(link);
    const size_t n = links_.size();
    if (s == 0.0) return poses_at_ends_[link];
    if (s == 0.5) return poses_at_ends_[n + link];
    if (s == 1.0) return poses_at_ends_[2 * n + link];
  }
  CheckMotionReady(link);
  return Compose(links_[link], s, X_WP);
}

LinkPose PairMotion::PoseAt(LinkIndex link, double s) const {
  if (!poses_at_ends_.empty() && (s == 0.0 || s == 0.5 || s == 1.0)) {
    CheckEndsReady(link);
    const size_t n = links_.size();
    if (s == 0.0) return poses_at_ends_[link];
    if (s == 0.5) return poses_at_ends_[n + link];
    if (s == 1.0) return poses_at_ends_[2 * n + link];
  }
  // Compose from the root down along the ancestors, iteratively (chains may
  // be deep). The same operations in the same order as PosesAt.
  LinkIndex chain[64];
  int count = 0;
  for (LinkIndex k = link; k.is_valid() && count < 64; k = links_[k].parent) chain[count++] = k;
  LinkPose out;
  int start = count - 1;
  if (links_[chain[start]].parent.is_valid()) {
    out = PoseAt(links_[chain[start]].parent, s);  // Deeper than 64: the rest first.
  }
  CheckMotionReady(link);  // Its ancestors' are then complete too.
  for (int j = start; j >= 0; --j) out = Compose(links_[chain[j]], s, out);  // From the parent's.
  return out;
}

void PairMotion::SegmentAt(LinkIndex link, double s, Eigen::Vector3d* p_WA,
                           Eigen::Vector3d* p_WB) const {
  const int k = s == 0.0 ? 0 : s == 0.5 ? 1 : s == 1.0 ? 2 : -1;
  if (k >= 0 && !segments_at_ends_.empty()) {
    CheckEndsReady(link);
    *p_WA = segments_at_ends_[6 * link + 2 * k];
    *p_WB = segments_at_ends_[6 * link + 2 * k + 1];
    return;
  }
  SegmentOfPose(link, PoseAt(link, s), p_WA, p_WB);
}

void PairMotion::SegmentOfPose(LinkIndex link, const LinkPose& X_WL, Eigen::Vector3d* p_WA,
                               Eigen::Vector3d* p_WB) const {
  const Eigen::Matrix3d R = X_WL.q.toRotationMatrix();
  *p_WA = X_WL.p + R * links_[link].a_L;
  *p_WB = X_WL.p + R * links_[link].b_L;
}

double PairMotion::SweepRadius(LinkIndex link, double s0, double s1) const {
  CheckMotionReady(link);
  const LinkMotion& m = links_[link];
  // (speed + angular * extent) * (s1 - s0) / 2 + slack, outward rounded.
  return internal::FirstOrderGrowth(m.bounds.speed, m.bounds.angular, m.extent, rounding_slack_, s0,
                                    s1);
}

void PairMotion::SweptCapsule(LinkIndex link, double s0, double s1, Eigen::Vector3d* p_WA,
                              Eigen::Vector3d* p_WB, double* growth) const {
  Eigen::Vector3d a0, b0, a1, b1;
  SegmentAt(link, s0, &a0, &b0);
  SegmentAt(link, s1, &a1, &b1);
  SweptCapsuleFromEnds(link, s0, s1, a0, b0, a1, b1, p_WA, p_WB, growth);
}

void PairMotion::SweptCapsuleFromEnds(LinkIndex link, double s0, double s1,
                                      const Eigen::Vector3d& a0, const Eigen::Vector3d& b0,
                                      const Eigen::Vector3d& a1, const Eigen::Vector3d& b1,
                                      Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB,
                                      double* growth) const {
  Eigen::Vector3d am, bm;
  SegmentAt(link, 0.5 * (s0 + s1), &am, &bm);
  SweptCapsuleFromSegments(link, s0, s1, a0, b0, a1, b1, am, bm, p_WA, p_WB, growth);
}

void PairMotion::SweptCapsuleFromSegments(LinkIndex link, double s0, double s1,
                                          const Eigen::Vector3d& a0, const Eigen::Vector3d& b0,
                                          const Eigen::Vector3d& a1, const Eigen::Vector3d& b1,
                                          const Eigen::Vector3d& am, const Eigen::Vector3d& bm,
                                          Eigen::Vector3d* p_WA, Eigen::Vector3d* p_WB,
                                          double* growth) const {
  const LinkMotion& m = links_[link];
  *p_WA = am;
  *p_WB = bm;
  const double first_order = SweepRadius(link, s0, s1);
  // Any link point x: |P''| <= |p''| + (|w'| + |w|^2) |x|. Each of the
  // three evaluated segments is off by at most rounding_slack_.
  const double chord = MaxNormHi(a1 - a0, b1 - b0);
  const double second_order =
      internal::SecondOrderGrowth(chord, m.bounds.accel, m.bounds.angular_accel, m.bounds.angular,
                                  m.extent, rounding_slack_, s0, s1);
  *growth = std::min(first_order, second_order);
}

double PairMotion::SecondOrderRadius(LinkIndex link, double chord, double s0, double s1) const {
  CheckMotionReady(link);
  const LinkMotion& m = links_[link];
  return internal::SecondOrderGrowth(chord, m.bounds.accel, m.bounds.angular_accel,
                                     m.bounds.angular, m.extent, rounding_slack_, s0, s1);
}

}  // namespace sweptccd
