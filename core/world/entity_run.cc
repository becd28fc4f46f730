#include "core/world/entity_run.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.h"
#include "core/geometry/rounding_slack.h"
#include "core/query/certificate.h"
#include "core/world/link_sweep_boxes.h"
#include "core/world/near_link_boxes.h"

namespace sweptccd::world {
namespace {

// The queue is a binary heap under Later, as std::priority_queue keeps it
// (push_heap / pop_heap).
struct Later {
  bool operator()(const EntityItem& x, const EntityItem& y) const {
    if (x.tau0 != y.tau0) return x.tau0 > y.tau0;
    if (x.link != y.link) return x.link > y.link;
    return x.piece > y.piece;
  }
};

}  // namespace

EntityRun::EntityRun(const Skeleton& skeleton_a, MotionMemo* memo_a, int64_t utime0, int64_t utime1,
                     const std::vector<Piece>& pieces, const OtherTarget& target,
                     const EntityQueryOptions& options, const std::vector<Aabb>* link_boxes_a,
                     const std::vector<Aabb>* near_boxes_a)
    : skeleton_a_(skeleton_a),
      memo_a_(*memo_a),
      pieces_(pieces),
      target_(target),
      options_(options),
      link_boxes_a_(link_boxes_a),
      near_boxes_a_(near_boxes_a),
      num_links_(skeleton_a.num_links()),
      num_pieces_(pieces.size()),
      dur_(static_cast<double>(utime1 - utime0)),
      done_(static_cast<size_t>(num_links_), false) {
  if (pieces.empty()) return;
  tau_from_ = pieces.front().tau0;
  tau_to_ = pieces.back().tau1;
  tol_ = RoundingSlack(memo_a_.motion().coordinate_scale(), target.tolerance());
  // G2 in printed microseconds: leave room for rounding utime0 + tau.
  const double ulp = std::ldexp(1.0, std::ilogb(std::fabs(static_cast<double>(utime1)) + 1.0) - 50);
  eps_us_ = std::max(options.eps_s * 1e6 - 4 * ulp, 0.5 * options.eps_s * 1e6);
  accept_ = AcceptedSeparation(options.delta_m, tol_);
}

EntityRun::~EntityRun() {
  constexpr size_t kKeptLists = 4096;
  constexpr size_t kKept = size_t{1} << 16;
  EntityScratch& s = *scratch_;
  FreeIfAbove(&s.roots, kKeptLists);
  FreeIfAbove(&s.cands, kKeptLists);
  FreeIfAbove(&s.boxes_e, kKept);
  FreeIfAbove(&s.piece_boxes, kKept);
  FreeIfAbove(&s.unions, kKept);
  FreeIfAbove(&s.near_e, kKept);
  FreeIfAbove(&s.near_unions, kKept);
  FreeIfAbove(&s.queue, kKept);
  FreeIfAbove(&s.arena, kKept);
  FreeIfAbove(&s.work, kKept);
}

OtherAnswer EntityRun::Run() {
  if (pieces_.empty()) return answer_;  // No window (a non-overlapping entity).
  FindRoots();
  // Nothing near in any piece, link by link: `free` with no pose composed.
  if (LinkBoxesClearAll()) {
    answer_.culled_by_box = true;
    return answer_;
  }
  // Apart as entities: nothing touches, at the window's start either.
  if (!EntityBoxesMeet()) {
    answer_.culled_by_box = true;
    return answer_;
  }
  CloseTouchingAtStart();
  SeedRoots();
  Descend();
  Assemble();
  return answer_;
}

double EntityRun::SOf(double tau) const { return std::clamp(tau / dur_, 0.0, 1.0); }

const std::vector<int>& EntityRun::CandidatesOf(int link, size_t piece) {
  return use_cands_ ? scratch_->cands[static_cast<size_t>(link) * num_pieces_ + piece]
                    : scratch_->roots[static_cast<size_t>(link)];
}

void EntityRun::FindRoots() {
  std::vector<std::vector<int>>& roots = scratch_->roots;
  if (roots.size() < static_cast<size_t>(num_links_)) roots.resize(num_links_);
  for (LinkIndex l(0); l < num_links_; ++l) target_.RootCandidatesInto(l, &roots[l]);
}

// Link-level broad phase (link_sweep_boxes.h): the candidates of A's link
// l over piece p, cands[l * num_pieces + p], are its roots less E's links
// whose box over p's sample interval is apart from l's box over the pair
// by more than the descent's slack on A's side (2 tol, with a relative
// 1e-8 for the rounding of A's box radius). Every Cull and Nearest of the
// descent would drop those (their boxes lie inside these), so the
// descent's answer is unchanged; when none is left anywhere, it is `free`
// (every item culled, none past the work limit, none touching at the
// start) with no pose composed: then true.
//
// With near boxes on both sides (near_link_boxes.h), a pair whose near
// boxes are apart leaves the candidates too: its capsules stay more than
// delta (plus the slack) apart over the whole motion, so no item of the
// descent could close a bracket on it (Nearest's sample separations would
// all be over delta) or find it touching at the start; dropping it only
// spares the items that would have culled it later.
bool EntityRun::LinkBoxesClearAll() {
  EntityScratch& scratch = *scratch_;
  std::vector<Aabb>& boxes_e = scratch.boxes_e;  // Piece p's link j at p * num_e + j.
  boxes_e.clear();
  size_t num_e = 0;
  bool have = true;
  std::vector<Aabb>& piece_boxes = scratch.piece_boxes;
  piece_boxes.clear();
  for (size_t p = 0; p < num_pieces_ && have; ++p) {
    have = target_.LinkBoxes(pieces_[p], &piece_boxes);
    if (p == 0) num_e = piece_boxes.size();
    have = have && piece_boxes.size() == num_e;
    boxes_e.insert(boxes_e.end(), piece_boxes.begin(), piece_boxes.end());
  }
  if (!have) {
    NearBoxesPruneRoots();
    return false;
  }
  std::vector<Aabb> own_boxes;
  if (link_boxes_a_ == nullptr) {
    own_boxes = LinkSweepBoxes(skeleton_a_, memo_a_.motion(), 0.0);
    link_boxes_a_ = &own_boxes;
  }
  SWEPTCCD_CHECK(static_cast<int>(link_boxes_a_->size()) == num_links_);
  const double margin = 2 * tol_ * (1 + 1e-8);
  std::vector<Aabb>& unions = scratch.unions;
  unions.assign(num_pieces_, Aabb::Empty());
  for (size_t p = 0; p < num_pieces_; ++p) {
    for (size_t j = 0; j < num_e; ++j) unions[p].Grow(boxes_e[p * num_e + j]);
  }
  const bool use_near = GatherNearBoxes(num_e);
  const std::vector<Aabb>& near_e = scratch.near_e;
  const std::vector<Aabb>& near_unions = scratch.near_unions;
  // One pass: a link apart from the union of E's boxes over a piece is
  // apart from each of them (each lies inside the union), so its list
  // stays empty without testing them.
  std::vector<std::vector<int>>& cands = scratch.cands;
  const size_t num_cands = static_cast<size_t>(num_links_) * num_pieces_;
  if (cands.size() < num_cands) cands.resize(num_cands);
  for (size_t i = 0; i < num_cands; ++i) cands[i].clear();
  use_cands_ = true;
  int64_t root_items = 0;
  bool any = false;
  for (int l = 0; l < num_links_; ++l) {
    const std::vector<int>& roots = scratch.roots[static_cast<size_t>(l)];
    if (roots.empty()) continue;
    const Aabb& box_a = (*link_boxes_a_)[static_cast<size_t>(l)];
    const Aabb* near_a = use_near ? &(*near_boxes_a_)[static_cast<size_t>(l)] : nullptr;
    for (size_t p = 0; p < num_pieces_; ++p) {
      ++root_items;
      if (BoxesApart(box_a, unions[p], margin)) continue;
      if (near_a != nullptr && BoxesApart(*near_a, near_unions[p])) continue;
      std::vector<int>& c = cands[static_cast<size_t>(l) * num_pieces_ + p];
      for (int j : roots) {
        const size_t i = p * num_e + static_cast<size_t>(j);
        if (!BoxesApart(box_a, boxes_e[i], margin) &&
            (near_a == nullptr || !BoxesApart(*near_a, near_e[i]))) {
          c.push_back(j);
        }
      }
      any = any || !c.empty();
    }
  }
  // (Own boxes die here: nothing below reads them.)
  if (link_boxes_a_ == &own_boxes) link_boxes_a_ = nullptr;
  return !any && root_items <= options_.max_intervals;
}

// A target without link boxes (an object): a root candidate whose near box
// is apart from A's link's in every piece leaves the link's roots (the
// link can come no nearer than delta to it over the window, so no item of
// the descent could close a bracket on it or find it touching at the start;
// a link left with no root is never seeded, as a filtered one).
void EntityRun::NearBoxesPruneRoots() {
  if (num_links_ == 0 || !GatherNearBoxes(0)) return;
  const std::vector<Aabb>& near_e = scratch_->near_e;
  const size_t num_e = near_e.size() / num_pieces_;
  for (int l = 0; l < num_links_; ++l) {
    std::vector<int>& roots = scratch_->roots[static_cast<size_t>(l)];
    const Aabb& near_a = (*near_boxes_a_)[static_cast<size_t>(l)];
    size_t kept = 0;
    for (int j : roots) {
      bool near = static_cast<size_t>(j) >= num_e;  // No box: kept.
      for (size_t p = 0; p < num_pieces_ && !near; ++p) {
        near = !BoxesApart(near_a, near_e[p * num_e + static_cast<size_t>(j)]);
      }
      if (near) roots[kept++] = j;
    }
    roots.resize(kept);
  }
}

// E's near boxes of every piece into near_e (as boxes_e) and their unions
// per piece: true when A and the target both have them, for every piece,
// one per link of A and num_e per piece (0: as many as the first piece's).
bool EntityRun::GatherNearBoxes(size_t num_e) {
  const double margin = NearMargin(options_.delta_m);
  EntityScratch& scratch = *scratch_;
  std::vector<Aabb>& near_e = scratch.near_e;
  std::vector<Aabb>& piece_boxes = scratch.piece_boxes;
  near_e.clear();
  scratch.near_unions.assign(num_pieces_, Aabb::Empty());
  for (size_t p = 0; p < num_pieces_; ++p) {
    if (!target_.NearLinkBoxes(pieces_[p], margin, &piece_boxes)) return false;
    if (num_e == 0 && p == 0) num_e = piece_boxes.size();
    if (piece_boxes.size() != num_e) return false;
    for (const Aabb& b : piece_boxes) scratch.near_unions[p].Grow(b);
    near_e.insert(near_e.end(), piece_boxes.begin(), piece_boxes.end());
  }
  // A's: the caller's, else made here (through A's memo: the same bits).
  if (near_boxes_a_ == nullptr || static_cast<int>(near_boxes_a_->size()) != num_links_) {
    own_near_ = NearLinkBoxes(skeleton_a_, &memo_a_, margin);
    near_boxes_a_ = &own_near_;
  }
  return true;
}

// Entity-level broad phase: A's box over the window against E's per piece.
// Apart, nothing touches, at the window's start either (the boxes hold the
// certified swept bounds and the slack), so the answer is the same as with
// the start tested first, without composing E's links.
bool EntityRun::EntityBoxesMeet() {
  Aabb box_a = Aabb::Empty();
  double s0 = SOf(tau_from_), s1 = SOf(tau_to_);
  WidenS(&s0, &s1);
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (scratch_->roots[static_cast<size_t>(l)].empty()) continue;
    Eigen::Vector3d a, b;
    double g;
    memo_a_.SweptCapsule(l, s0, s1, &a, &b, &g);
    box_a.Grow(Aabb::OfCapsule(a, b, skeleton_a_.link(l).radius + g + tol_));
  }
  bool overlaps = false;
  for (const Piece& p : pieces_) {
    overlaps = overlaps || target_.PieceBoxMeets(p, p.tau0, p.tau1, box_a);
  }
  return overlaps;
}

// Initially colliding: touching at the window's start.
void EntityRun::CloseTouchingAtStart() {
  for (LinkIndex l(0); l < num_links_ && Searching(); ++l) {
    if (scratch_->roots[static_cast<size_t>(l)].empty()) continue;
    Eigen::Vector3d a, b;
    memo_a_.SegmentAt(l, SOf(tau_from_), &a, &b);
    OtherContact c;
    if (target_.Nearest(pieces_.front(), tau_from_, l, a, b, skeleton_a_.link(l).radius,
                        CandidatesOf(l, 0), 0.0, &c) &&
        c.separation <= 0) {
      OtherBracket br;
      br.link = l;
      br.tau_lo = tau_from_;
      br.tau_hi = std::min(tau_to_, tau_from_ + eps_us_);
      br.initially_colliding = true;
      br.has_witness = true;
      br.witness = c;
      Close(br);
    }
  }
}

// Candidate lists live in one arena (no allocation per item); `work` holds
// the popped item's while Cull narrows it. Lists of items no longer queued
// are dropped when the arena has doubled since it was last compacted.
void EntityRun::Push(const EntityItem& item) {
  std::vector<EntityItem>& queue = scratch_->queue;
  queue.push_back(item);
  std::push_heap(queue.begin(), queue.end(), Later());
}

size_t EntityRun::Store(const std::vector<int>& list) {
  std::vector<int>& arena = scratch_->arena;
  const size_t off = arena.size();
  arena.insert(arena.end(), list.begin(), list.end());
  return off;
}

void EntityRun::SeedRoots() {
  scratch_->queue.clear();
  scratch_->arena.clear();
  for (LinkIndex l(0); l < num_links_; ++l) {
    if (done_[static_cast<size_t>(l)] || scratch_->roots[static_cast<size_t>(l)].empty()) continue;
    for (int p = 0; p < static_cast<int>(num_pieces_); ++p) {
      const std::vector<int>& c = CandidatesOf(l, static_cast<size_t>(p));
      Push(EntityItem{pieces_[p].tau0, pieces_[p].tau1, l, p, Store(c), c.size()});
    }
  }
}

void EntityRun::Descend() {
  std::vector<EntityItem>& queue = scratch_->queue;
  while (!queue.empty() && Searching()) {
    std::pop_heap(queue.begin(), queue.end(), Later());
    const EntityItem item = queue.back();
    queue.pop_back();
    if (done_[static_cast<size_t>(item.link)]) continue;
    if (++answer_.intervals > options_.max_intervals) {
      CloseOutOfWork(item);
      break;
    }
    if (Visit(item) == Step::kStop) break;
  }
}

EntityRun::Step EntityRun::Visit(const EntityItem& item) {
  // No candidate left by the link boxes: Cull would keep none.
  if (item.len == 0) return Step::kNext;
  std::vector<int>& work = scratch_->work;
  const std::vector<int>& arena = scratch_->arena;
  work.assign(arena.begin() + static_cast<std::ptrdiff_t>(item.off),
              arena.begin() + static_cast<std::ptrdiff_t>(item.off + item.len));
  const double r_a = skeleton_a_.link(item.link).radius;
  double s0 = SOf(item.tau0), s1 = SOf(item.tau1);
  WidenS(&s0, &s1);
  Eigen::Vector3d a, b;
  double g;
  memo_a_.SweptCapsule(item.link, s0, s1, &a, &b, &g);
  target_.Cull(pieces_[item.piece], item.tau0, item.tau1, a, b, r_a + tol_, g, &work);
  if (work.empty()) return Step::kNext;  // Certified free over the item.
  if (item.tau1 - item.tau0 <= eps_us_ && TryClose(item)) return Step::kNext;
  const double mid = 0.5 * (item.tau0 + item.tau1);
  if (!(mid > item.tau0 && mid < item.tau1)) {
    OtherBracket br;  // Cannot split further.
    br.link = item.link;
    br.tau_lo = item.tau0;
    br.tau_hi = tau_to_;
    br.undecided = true;
    CloseUndecided(br);
    return Step::kNext;
  }
  CompactArena();
  const size_t off = Store(work);
  Push(EntityItem{item.tau0, mid, item.link, item.piece, off, work.size()});
  Push(EntityItem{mid, item.tau1, item.link, item.piece, off, work.size()});
  return Step::kNext;
}

bool EntityRun::TryClose(const EntityItem& item) {
  const Piece& piece = pieces_[item.piece];
  const double r_a = skeleton_a_.link(item.link).radius;
  OtherContact best, c;
  bool have = false;
  const double mid = 0.5 * (item.tau0 + item.tau1);
  for (double tau : {item.tau0, mid, item.tau1}) {
    Eigen::Vector3d sa, sb;
    memo_a_.SegmentAt(item.link, SOf(tau), &sa, &sb);
    if (target_.Nearest(piece, tau, item.link, sa, sb, r_a, scratch_->work, options_.delta_m, &c) &&
        (!have || c.separation < best.separation)) {
      best = c;
      have = true;
    }
  }
  if (!have || best.separation > accept_) return false;
  OtherBracket br;
  br.link = item.link;
  br.tau_lo = item.tau0;
  br.tau_hi = item.tau1;
  br.has_witness = true;
  br.witness = best;
  Close(br);
  return true;
}

void EntityRun::CompactArena() {
  std::vector<int>& arena = scratch_->arena;
  if (arena.size() <= std::max<size_t>(2 * compacted_, 1 << 16)) return;
  std::vector<int> live;  // Only the queued items' lists (order kept).
  for (EntityItem& t : scratch_->queue) {
    const size_t off = live.size();
    live.insert(live.end(), arena.begin() + static_cast<std::ptrdiff_t>(t.off),
                arena.begin() + static_cast<std::ptrdiff_t>(t.off + t.len));
    t.off = off;
  }
  arena.swap(live);
  compacted_ = arena.size();
}

// Out of work: every open link undecided from its earliest item
// (certificate.h).
void EntityRun::CloseOutOfWork(const EntityItem& item) {
  std::vector<EntityItem>& queue = scratch_->queue;
  OpenWork open(num_links_);
  open.Note(item.link, item.tau0);
  for (const EntityItem& t : queue) {
    if (!done_[static_cast<size_t>(t.link)]) open.Note(t.link, t.tau0);
  }
  queue.clear();
  for (LinkIndex l : open.ByEarliest()) {
    if (!Searching()) break;
    OtherBracket br;
    br.link = l;
    br.tau_lo = open.earliest(l);
    br.tau_hi = tau_to_;
    br.undecided = true;
    CloseUndecided(br);
  }
}

void EntityRun::Close(const OtherBracket& b) {
  done_[static_cast<size_t>(b.link)] = true;
  brackets_.push_back(b);
}

void EntityRun::CloseUndecided(OtherBracket b) {
  size_t p = 0;
  while (p + 1 < num_pieces_ && pieces_[p].tau1 < b.tau_lo) ++p;
  Eigen::Vector3d sa, sb;
  memo_a_.SegmentAt(b.link, SOf(b.tau_lo), &sa, &sb);
  OtherContact c;
  if (target_.Nearest(pieces_[p], b.tau_lo, b.link, sa, sb, skeleton_a_.link(b.link).radius,
                      scratch_->roots[static_cast<size_t>(b.link)],
                      std::numeric_limits<double>::infinity(), &c)) {
    b.has_witness = true;
    b.witness = c;
  }
  Close(b);
}

void EntityRun::Assemble() {
  if (brackets_.empty()) return;
  answer_.contact = true;
  answer_.bracket = brackets_.front();
  for (const OtherBracket& b : brackets_) {
    if (b.tau_lo < answer_.bracket.tau_lo) answer_.bracket = b;
  }
  if (options_.per_link) {
    answer_.links = brackets_;
    std::sort(answer_.links.begin(), answer_.links.end(),
              [](const OtherBracket& x, const OtherBracket& y) { return x.link < y.link; });
  }
}

OtherAnswer AnswerOther(const Skeleton& skeleton_a, const PairMotion& motion_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options) {
  MotionMemo memo_a(motion_a);
  return AnswerOther(skeleton_a, &memo_a, utime0, utime1, pieces, target, options);
}

OtherAnswer AnswerOther(const Skeleton& skeleton_a, MotionMemo* memo_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options, const std::vector<Aabb>* link_boxes_a,
                        const std::vector<Aabb>* near_boxes_a) {
  return EntityRun(skeleton_a, memo_a, utime0, utime1, pieces, target, options, link_boxes_a,
                   near_boxes_a)
      .Run();
}

}  // namespace sweptccd::world
