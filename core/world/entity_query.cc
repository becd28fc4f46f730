#include "core/world/entity_query.h"

#include <algorithm>
#include <cmath>

#include "core/query/ccd_query.h"
#include "core/world/avatar_target.h"
#include "core/world/entity_run.h"
#include "core/world/object_target.h"

namespace sweptccd::world {

OtherAnswer AnswerAgainstAvatar(const PairSide& a, const AvatarWindow& b, const EntryWindow& window,
                                const EntityQueryOptions& options, double scale,
                                IntervalMotions* motions) {
  // The rounding slack from the window's samples only (WindowScale): what
  // a live service holding only those answers with too.
  if (scale < 0) scale = WindowScale(b, window.pieces);
  const std::unique_ptr<OtherTarget> target = MakeAvatarTarget(a.who, b, scale, motions);
  return AnswerOther(a.skeleton, a.memo, a.utime0, a.utime1, window.pieces, *target, options,
                     a.link_boxes, a.near_link_boxes);
}

OtherAnswer AnswerAgainstObject(const PairSide& a, const ObjectWindow& o, const EntryWindow& window,
                                const EntityQueryOptions& options, double scale) {
  if (scale < 0) scale = WindowScale(o, window.pieces);
  const std::unique_ptr<OtherTarget> target = MakeObjectTarget(a.who, o, scale);
  // (An object has no link boxes: A's are not needed.)
  return AnswerOther(a.skeleton, a.memo, a.utime0, a.utime1, window.pieces, *target, options,
                     nullptr, a.near_link_boxes);
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

EntityContactRecord ContactRecordOf(const OtherContact& c, double dur) {
  EntityContactRecord r;
  r.link = c.link;
  r.other_link = c.other_link;
  r.triangle = c.triangle;
  r.s = std::clamp(c.tau / dur, 0.0, 1.0);
  r.point_link = c.point_link;
  r.point_other = c.point_other;
  r.normal = c.normal;
  r.separation = c.separation;
  return r;
}

}  // namespace

EntityBracketRecord PrintBracket(const OtherBracket& b, int64_t utime0, int64_t utime1,
                                 int64_t t_from, int64_t t_to) {
  const double dur = static_cast<double>(utime1 - utime0);
  EntityBracketRecord p;
  p.link = b.link;
  p.initially_colliding = b.initially_colliding;
  p.undecided = b.undecided;
  const double s_lo = RoundedS(b.tau_lo, dur, false);
  p.s_lo = b.initially_colliding ? static_cast<double>(t_from - utime0) / dur : s_lo;
  p.s_hi = RoundedS(b.tau_hi, dur, true);
  // Inside the window (the rounding of s must not move a bracket end out).
  p.t_lo = b.initially_colliding
               ? static_cast<double>(t_from)
               : std::max(BracketTimeLo(utime0, utime1, s_lo), static_cast<double>(t_from));
  p.t_hi = std::min(BracketTimeHi(utime0, utime1, p.s_hi), static_cast<double>(t_to));
  p.has_witness = b.has_witness;
  if (b.has_witness) p.witness = ContactRecordOf(b.witness, dur);
  return p;
}

EntityRecord MakeEntityRecord(const std::string& entity, bool is_object, int64_t utime0,
                              int64_t utime1, int64_t t_from, int64_t t_to,
                              const OtherAnswer& answer, bool per_link) {
  EntityRecord r;
  r.entity = entity;
  r.is_object = is_object;
  r.t_from = t_from;
  r.t_to = t_to;
  r.contact = answer.contact;
  if (answer.contact) {
    r.bracket = PrintBracket(answer.bracket, utime0, utime1, t_from, t_to);
    if (r.bracket.has_witness) r.contacts.push_back(r.bracket.witness);
  }
  r.per_link = per_link;
  if (per_link) {
    for (const OtherBracket& b : answer.links) {
      r.links.push_back(PrintBracket(b, utime0, utime1, t_from, t_to));
    }
  }
  r.intervals = answer.intervals;
  r.culled_by_box = answer.culled_by_box;
  return r;
}

}  // namespace sweptccd::world
