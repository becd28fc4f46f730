#include "service/ws/lcm_json.h"

#include <cstring>
#include <limits>

#include "service/ws/json_fields.h"

namespace sweptccd::ws {

namespace {

constexpr int64_t kI32Min = std::numeric_limits<int32_t>::min();
constexpr int64_t kI32Max = std::numeric_limits<int32_t>::max();
constexpr int64_t kI8Min = -128, kI8Max = 127;
constexpr int64_t kAny = kMaxSafeInteger;

OrderedJson Vec(const double* v, int n) {
  OrderedJson a = OrderedJson::array();
  for (int i = 0; i < n; ++i) a.push_back(v[i]);
  return a;
}

template <class T>
OrderedJson List(const std::vector<T>& v) {
  OrderedJson a = OrderedJson::array();
  for (const T& x : v) a.push_back(x);
  return a;
}

OrderedJson Rows(const std::vector<std::vector<double>>& rows) {
  OrderedJson a = OrderedJson::array();
  for (const auto& r : rows) a.push_back(Vec(r.data(), static_cast<int>(r.size())));
  return a;
}

OrderedJson Record(const contact_record_t& c) {
  OrderedJson j;
  j["link"] = c.link;
  j["object"] = c.object;
  j["triangle"] = c.triangle;
  j["s"] = c.s;
  j["point_link"] = Vec(c.point_link, 3);
  j["point_env"] = Vec(c.point_env, 3);
  j["normal"] = Vec(c.normal, 3);
  j["separation"] = c.separation;
  return j;
}

OrderedJson Record(const entity_contact_t& c) {
  OrderedJson j;
  j["link"] = c.link;
  j["other_link"] = c.other_link;
  j["triangle"] = c.triangle;
  j["s"] = c.s;
  j["point_link"] = Vec(c.point_link, 3);
  j["point_other"] = Vec(c.point_other, 3);
  j["normal"] = Vec(c.normal, 3);
  j["separation"] = c.separation;
  return j;
}

// A link's bracket: the same fields for an avatar against the scene
// (link_bracket_t) and against another entity (entity_link_bracket_t); only
// the witness's record differs (Record's overloads).
template <class LinkBracket>
OrderedJson Bracket(const LinkBracket& b) {
  OrderedJson j;
  j["link"] = b.link;
  j["s_lo"] = b.s_lo;
  j["s_hi"] = b.s_hi;
  j["t_lo"] = b.t_lo;
  j["t_hi"] = b.t_hi;
  j["initially_colliding"] = b.initially_colliding != 0;
  j["undecided"] = b.undecided != 0;
  j["has_witness"] = b.has_witness != 0;
  j["witness"] = Record(b.witness);
  return j;
}

// An answer's fields, in this order: the same names and meaning in a
// contact_event_t (an avatar against the scene) and a shared_entry_t (against
// another entity); only the records' and brackets' types differ (Record's
// and Bracket's overloads). docs/WEBSOCKET.md lists them once for both.
template <class Answer>
void AddAnswer(const Answer& a, OrderedJson* j) {
  (*j)["result"] = static_cast<int>(a.result);
  (*j)["result_name"] = ResultName(a.result);
  (*j)["error"] = a.error;
  (*j)["initially_colliding"] = a.initially_colliding != 0;
  (*j)["undecided"] = a.undecided != 0;
  (*j)["s_lo"] = a.s_lo;
  (*j)["s_hi"] = a.s_hi;
  (*j)["t_lo"] = a.t_lo;
  (*j)["t_hi"] = a.t_hi;
  OrderedJson contacts = OrderedJson::array();
  for (const auto& c : a.contacts) contacts.push_back(Record(c));
  (*j)["contacts"] = std::move(contacts);
  OrderedJson links = OrderedJson::array();
  for (const auto& b : a.links) links.push_back(Bracket(b));
  (*j)["links"] = std::move(links);
}

OrderedJson Entry(const shared_entry_t& e) {
  OrderedJson j;
  j["entity"] = e.entity;
  j["entity_kind"] = static_cast<int>(e.entity_kind);
  j["entity_kind_name"] = e.entity_kind == shared_entry_t::KIND_AVATAR   ? "avatar"
                          : e.entity_kind == shared_entry_t::KIND_OBJECT ? "object"
                                                                         : "unknown";
  j["t_from"] = e.t_from;
  j["t_to"] = e.t_to;
  AddAnswer(e, &j);
  j["waited_us"] = e.waited_us;
  j["ended_by_timeout"] = e.ended_by_timeout != 0;
  j["compute_us"] = e.compute_us;
  j["queue_us"] = e.queue_us;
  return j;
}

// Readers.

void RecordFrom(const nlohmann::json& v, const std::string& where, contact_record_t* c) {
  const Fields f(v, where);
  c->link = static_cast<int32_t>(f.Int("link", kI32Min, kI32Max));
  c->object = static_cast<int32_t>(f.Int("object", kI32Min, kI32Max));
  c->triangle = f.Int("triangle", -kAny, kAny);
  c->s = f.RealOrNull("s");
  RealsAt(f.Get("point_link"), f.Path("point_link"), 3, c->point_link, true);
  RealsAt(f.Get("point_env"), f.Path("point_env"), 3, c->point_env, true);
  RealsAt(f.Get("normal"), f.Path("normal"), 3, c->normal, true);
  c->separation = f.RealOrNull("separation");
}

void RecordFrom(const nlohmann::json& v, const std::string& where, entity_contact_t* c) {
  const Fields f(v, where);
  c->link = static_cast<int32_t>(f.Int("link", kI32Min, kI32Max));
  c->other_link = static_cast<int32_t>(f.Int("other_link", kI32Min, kI32Max));
  c->triangle = f.Int("triangle", -kAny, kAny);
  c->s = f.RealOrNull("s");
  RealsAt(f.Get("point_link"), f.Path("point_link"), 3, c->point_link, true);
  RealsAt(f.Get("point_other"), f.Path("point_other"), 3, c->point_other, true);
  RealsAt(f.Get("normal"), f.Path("normal"), 3, c->normal, true);
  c->separation = f.RealOrNull("separation");
}

// Reads either bracket type (Bracket above); the witness by RecordFrom's overloads.
template <class LinkBracket>
void BracketFrom(const nlohmann::json& v, const std::string& where, LinkBracket* b) {
  const Fields f(v, where);
  b->link = static_cast<int32_t>(f.Int("link", kI32Min, kI32Max));
  b->s_lo = f.RealOrNull("s_lo");
  b->s_hi = f.RealOrNull("s_hi");
  b->t_lo = f.RealOrNull("t_lo");
  b->t_hi = f.RealOrNull("t_hi");
  b->initially_colliding = f.Bool("initially_colliding");
  b->undecided = f.Bool("undecided");
  b->has_witness = f.Bool("has_witness");
  RecordFrom(f.Get("witness"), f.Path("witness"), &b->witness);
}

// Reads AddAnswer's fields into either message type, within the limits
// (records and brackets by RecordFrom's and BracketFrom's overloads).
template <class Answer>
void AnswerFrom(const Fields& f, const WireLimits& L, Answer* a) {
  a->result = static_cast<int8_t>(f.Int("result", kI8Min, kI8Max));
  a->error = f.String("error", static_cast<size_t>(L.max_text_bytes));
  a->initially_colliding = f.Bool("initially_colliding");
  a->undecided = f.Bool("undecided");
  a->s_lo = f.RealOrNull("s_lo");
  a->s_hi = f.RealOrNull("s_hi");
  a->t_lo = f.RealOrNull("t_lo");
  a->t_hi = f.RealOrNull("t_hi");
  const auto& contacts = f.Array("contacts", static_cast<size_t>(L.max_contacts));
  a->contacts.resize(contacts.size());
  for (size_t i = 0; i < contacts.size(); ++i) {
    RecordFrom(contacts[i], f.Path("contacts") + "[" + std::to_string(i) + "]", &a->contacts[i]);
  }
  a->num_contacts = static_cast<int32_t>(contacts.size());
  const auto& links = f.Array("links", static_cast<size_t>(L.max_links));
  a->links.resize(links.size());
  for (size_t i = 0; i < links.size(); ++i) {
    BracketFrom(links[i], f.Path("links") + "[" + std::to_string(i) + "]", &a->links[i]);
  }
  a->num_links = static_cast<int32_t>(links.size());
}

void EntryFrom(const nlohmann::json& v, const std::string& where, const WireLimits& L,
               shared_entry_t* e) {
  const Fields f(v, where);
  e->entity = f.String("entity", static_cast<size_t>(L.max_id_bytes));
  e->entity_kind = static_cast<int8_t>(f.Int("entity_kind", kI8Min, kI8Max));
  e->t_from = f.Int("t_from", -kAny, kAny);
  e->t_to = f.Int("t_to", -kAny, kAny);
  AnswerFrom(f, L, e);
  e->waited_us = f.Int("waited_us", -kAny, kAny);
  e->ended_by_timeout = f.Bool("ended_by_timeout");
  e->compute_us = f.RealOrNull("compute_us");
  e->queue_us = f.RealOrNull("queue_us");
}

std::vector<std::string> Strings(const Fields& f, const char* name, size_t max_length,
                                 size_t max_bytes) {
  const auto& a = f.Array(name, max_length);
  std::vector<std::string> out;
  out.reserve(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    out.push_back(StringAt(a[i], f.Path(name) + "[" + std::to_string(i) + "]", max_bytes));
  }
  return out;
}

// Optional string arrays of a join (absent: empty).
std::vector<std::string> OptionalStrings(const Fields& f, const char* name, size_t max_length,
                                         size_t max_bytes) {
  if (!f.Find(name)) return {};
  return Strings(f, name, max_length, max_bytes);
}

std::vector<int64_t> Ints(const Fields& f, const char* name, size_t n, int64_t lo, int64_t hi) {
  const auto& a = f.Array(name, n);
  if (a.size() != n) {
    BadMessage(f.Path(name),
               "expected " + std::to_string(n) + " elements, got " + std::to_string(a.size()));
  }
  std::vector<int64_t> out(n);
  for (size_t i = 0; i < n; ++i)
    out[i] = IntAt(a[i], f.Path(name) + "[" + std::to_string(i) + "]", lo, hi);
  return out;
}

std::vector<double> Reals(const Fields& f, const char* name, size_t n, bool allow_null) {
  const auto& a = f.Array(name, n);
  if (a.size() != n) {
    BadMessage(f.Path(name),
               "expected " + std::to_string(n) + " elements, got " + std::to_string(a.size()));
  }
  std::vector<double> out(n);
  for (size_t i = 0; i < n; ++i) {
    const std::string at = f.Path(name) + "[" + std::to_string(i) + "]";
    out[i] = allow_null ? RealOrNullAt(a[i], at) : RealAt(a[i], at);
  }
  return out;
}

// n rows of `width` reals.
std::vector<std::vector<double>> RowsFrom(const Fields& f, const char* name, size_t n,
                                          size_t width) {
  const auto& a = f.Array(name, n);
  if (a.size() != n) {
    BadMessage(f.Path(name),
               "expected " + std::to_string(n) + " rows, got " + std::to_string(a.size()));
  }
  std::vector<std::vector<double>> out(n, std::vector<double>(width));
  for (size_t i = 0; i < n; ++i) {
    RealsAt(a[i], f.Path(name) + "[" + std::to_string(i) + "]", width, out[i].data());
  }
  return out;
}

}  // namespace

const char* JoinReasonName(int reason) {
  static const char* const kNames[] = {"accepted",         "bad_skeleton",   "id_in_use",
                                       "too_many_clients", "too_many_links", "bad_client_id",
                                       "bad_filter",       "bad_options",    "busy",
                                       "stale_request",    "joins_disabled"};
  if (reason < 0 || reason >= static_cast<int>(sizeof(kNames) / sizeof(kNames[0]))) {
    return "unknown";
  }
  return kNames[reason];
}

const char* ResultName(int result) {
  switch (result) {
    case contact_event_t::RESULT_FREE:
      return "free";
    case contact_event_t::RESULT_CONTACT:
      return "contact";
    case contact_event_t::RESULT_INVALID:
      return "invalid";
    default:
      return "unknown";
  }
}

OrderedJson ToJson(const contact_event_t& m) {
  OrderedJson j;
  j["type"] = "contact_event";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["seq0"] = m.seq0;
  j["seq1"] = m.seq1;
  j["pair"] = m.pair;
  j["utime0"] = m.utime0;
  j["utime1"] = m.utime1;
  AddAnswer(m, &j);
  j["receive_utime"] = m.receive_utime;
  j["compute_us"] = m.compute_us;
  j["queue_us"] = m.queue_us;
  j["skipped_pairs_total"] = m.skipped_pairs_total;
  return j;
}

OrderedJson ToJson(const shared_contact_t& m) {
  OrderedJson j;
  j["type"] = "shared_contact";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["seq0"] = m.seq0;
  j["seq1"] = m.seq1;
  j["pair"] = m.pair;
  j["utime0"] = m.utime0;
  j["utime1"] = m.utime1;
  j["receive_utime"] = m.receive_utime;
  OrderedJson entries = OrderedJson::array();
  for (const auto& e : m.entries) entries.push_back(Entry(e));
  j["entries"] = std::move(entries);
  return j;
}

OrderedJson ToJson(const rejection_t& m) {
  OrderedJson j;
  j["type"] = "rejection";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["seq"] = m.seq;
  j["reason"] = m.reason;
  j["message"] = m.message;
  j["suppressed"] = m.suppressed;
  return j;
}

OrderedJson ToJson(const status_t& m) {
  OrderedJson j;
  j["type"] = "status";
  j["utime"] = m.utime;
  j["backend"] = m.backend;
  j["renderer"] = m.renderer;
  j["security"] = m.security;
  j["client_id"] = List(m.client_id);
  j["poses_received"] = List(m.poses_received);
  j["pairs_answered"] = List(m.pairs_answered);
  j["pairs_skipped"] = List(m.pairs_skipped);
  j["rejected"] = List(m.rejected);
  j["seq_gaps"] = List(m.seq_gaps);
  j["rate_limited"] = List(m.rate_limited);
  j["latency_median_us"] = List(m.latency_median_us);
  j["latency_p99_us"] = List(m.latency_p99_us);
  j["queue_depth"] = m.queue_depth;
  j["dropped_total"] = m.dropped_total;
  j["rejected_unattributed"] = m.rejected_unattributed;
  j["rejections_suppressed"] = m.rejections_suppressed;
  j["instance"] = m.instance;
  j["live_joined"] = m.live_joined;
  j["live_left"] = m.live_left;
  j["live_expired"] = m.live_expired;
  j["shared_messages"] = m.shared_messages;
  j["shared_entries"] = m.shared_entries;
  j["shared_by_timeout"] = m.shared_by_timeout;
  j["shared_dropped"] = m.shared_dropped;
  j["shared_overflowed"] = m.shared_overflowed;
  j["shared_cleared"] = m.shared_cleared;
  j["shared_pending"] = m.shared_pending;
  j["shared_ready"] = m.shared_ready;
  j["object_poses_received"] = m.object_poses_received;
  j["object_poses_rejected"] = m.object_poses_rejected;
  j["object_poses_rate_limited"] = m.object_poses_rate_limited;
  return j;
}

OrderedJson ToJson(const join_reply_t& m) {
  OrderedJson j;
  j["type"] = "join_reply";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["nonce"] = m.nonce;
  j["reason"] = static_cast<int>(m.reason);
  j["reason_name"] = JoinReasonName(m.reason);
  j["message"] = m.message;
  j["session"] = m.session;
  j["instance"] = m.instance;
  j["silence_timeout_ms"] = m.silence_timeout_ms;
  return j;
}

OrderedJson ToJson(const join_request_t& m, const std::string& proof) {
  OrderedJson j;
  j["type"] = "join_request";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["nonce"] = m.nonce;
  j["motion"] = static_cast<int>(m.motion);
  j["eps_s"] = m.eps_s;
  j["delta_m"] = m.delta_m;
  j["link_name"] = List(m.link_name);
  j["parent"] = List(m.parent);
  OrderedJson a = OrderedJson::array(), b = OrderedJson::array();
  for (const auto& row : m.a) a.push_back(Vec(row.data(), static_cast<int>(row.size())));
  for (const auto& row : m.b) b.push_back(Vec(row.data(), static_cast<int>(row.size())));
  j["a"] = std::move(a);
  j["b"] = std::move(b);
  j["radius"] = List(m.radius);
  j["ignore"] = List(m.ignore);
  j["ignore_entity_link"] = List(m.ignore_entity_link);
  j["ignore_entity"] = List(m.ignore_entity);
  j["ignore_entity_other_link"] = List(m.ignore_entity_other_link);
  j["proof"] = proof;
  return j;
}

OrderedJson ToJson(const tracker_pose_t& m) {
  OrderedJson j;
  j["type"] = "tracker_pose";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["session"] = m.session;
  j["seq"] = m.seq;
  j["position"] = Rows(m.position);
  j["orientation"] = Rows(m.orientation);
  return j;
}

OrderedJson ToJson(const leave_t& m) {
  OrderedJson j;
  j["type"] = "leave";
  j["utime"] = m.utime;
  j["client_id"] = m.client_id;
  j["session"] = m.session;
  return j;
}

OrderedJson ToJson(const object_pose_t& m) {
  OrderedJson j;
  j["type"] = "object_pose";
  j["utime"] = m.utime;
  j["object_id"] = m.object_id;
  j["session"] = m.session;
  j["seq"] = m.seq;
  j["position"] = Vec(m.position, 3);
  j["orientation"] = Vec(m.orientation, 4);
  return j;
}

void FromJson(const nlohmann::json& v, const WireLimits& L, contact_event_t* m) {
  const Fields f(v, "contact_event");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->seq0 = f.Int("seq0", -kAny, kAny);
  m->seq1 = f.Int("seq1", -kAny, kAny);
  m->pair = f.Int("pair", -kAny, kAny);
  m->utime0 = f.Int("utime0", -kAny, kAny);
  m->utime1 = f.Int("utime1", -kAny, kAny);
  AnswerFrom(f, L, m);
  m->receive_utime = f.Int("receive_utime", -kAny, kAny);
  m->compute_us = f.RealOrNull("compute_us");
  m->queue_us = f.RealOrNull("queue_us");
  m->skipped_pairs_total = f.Int("skipped_pairs_total", -kAny, kAny);
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, shared_contact_t* m) {
  const Fields f(v, "shared_contact");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->seq0 = f.Int("seq0", -kAny, kAny);
  m->seq1 = f.Int("seq1", -kAny, kAny);
  m->pair = f.Int("pair", -kAny, kAny);
  m->utime0 = f.Int("utime0", -kAny, kAny);
  m->utime1 = f.Int("utime1", -kAny, kAny);
  m->receive_utime = f.Int("receive_utime", -kAny, kAny);
  const auto& entries = f.Array("entries", static_cast<size_t>(L.max_shared_entries));
  m->entries.resize(entries.size());
  for (size_t i = 0; i < entries.size(); ++i) {
    EntryFrom(entries[i], f.Path("entries") + "[" + std::to_string(i) + "]", L, &m->entries[i]);
  }
  m->num_entries = static_cast<int32_t>(entries.size());
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, rejection_t* m) {
  const Fields f(v, "rejection");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->seq = f.Int("seq", -kAny, kAny);
  m->reason = f.String("reason", static_cast<size_t>(L.max_text_bytes));
  m->message = f.String("message", static_cast<size_t>(L.max_text_bytes));
  m->suppressed = f.Int("suppressed", -kAny, kAny);
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, status_t* m) {
  const Fields f(v, "status");
  m->utime = f.Int("utime", -kAny, kAny);
  m->backend = f.String("backend", static_cast<size_t>(L.max_text_bytes));
  m->renderer = f.String("renderer", static_cast<size_t>(L.max_text_bytes));
  m->security = f.String("security", static_cast<size_t>(L.max_text_bytes));
  m->client_id = Strings(f, "client_id", static_cast<size_t>(L.max_clients),
                         static_cast<size_t>(L.max_id_bytes));
  const size_t n = m->client_id.size();
  m->num_clients = static_cast<int32_t>(n);
  m->poses_received = Ints(f, "poses_received", n, -kAny, kAny);
  m->pairs_answered = Ints(f, "pairs_answered", n, -kAny, kAny);
  m->pairs_skipped = Ints(f, "pairs_skipped", n, -kAny, kAny);
  m->rejected = Ints(f, "rejected", n, -kAny, kAny);
  m->seq_gaps = Ints(f, "seq_gaps", n, -kAny, kAny);
  m->rate_limited = Ints(f, "rate_limited", n, -kAny, kAny);
  m->latency_median_us = Reals(f, "latency_median_us", n, true);
  m->latency_p99_us = Reals(f, "latency_p99_us", n, true);
  m->queue_depth = static_cast<int32_t>(f.Int("queue_depth", kI32Min, kI32Max));
  m->dropped_total = f.Int("dropped_total", -kAny, kAny);
  m->rejected_unattributed = f.Int("rejected_unattributed", -kAny, kAny);
  m->rejections_suppressed = f.Int("rejections_suppressed", -kAny, kAny);
  m->instance = f.Int("instance", -kAny, kAny);
  m->live_joined = f.Int("live_joined", -kAny, kAny);
  m->live_left = f.Int("live_left", -kAny, kAny);
  m->live_expired = f.Int("live_expired", -kAny, kAny);
  m->shared_messages = f.Int("shared_messages", -kAny, kAny);
  m->shared_entries = f.Int("shared_entries", -kAny, kAny);
  m->shared_by_timeout = f.Int("shared_by_timeout", -kAny, kAny);
  m->shared_dropped = f.Int("shared_dropped", -kAny, kAny);
  m->shared_overflowed = f.Int("shared_overflowed", -kAny, kAny);
  m->shared_cleared = f.Int("shared_cleared", -kAny, kAny);
  m->shared_pending = static_cast<int32_t>(f.Int("shared_pending", kI32Min, kI32Max));
  m->shared_ready = static_cast<int32_t>(f.Int("shared_ready", kI32Min, kI32Max));
  m->object_poses_received = f.Int("object_poses_received", -kAny, kAny);
  m->object_poses_rejected = f.Int("object_poses_rejected", -kAny, kAny);
  m->object_poses_rate_limited = f.Int("object_poses_rate_limited", -kAny, kAny);
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, join_reply_t* m) {
  const Fields f(v, "join_reply");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->nonce = f.Int("nonce", -kAny, kAny);
  m->reason = static_cast<int8_t>(f.Int("reason", kI8Min, kI8Max));
  m->message = f.String("message", static_cast<size_t>(L.max_text_bytes));
  m->session = f.Int("session", -kAny, kAny);
  m->instance = f.Int("instance", -kAny, kAny);
  m->silence_timeout_ms = f.Int("silence_timeout_ms", -kAny, kAny);
  m->sealed_key_size = 0;
  m->sealed_key.clear();
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, join_request_t* m, std::string* proof) {
  const Fields f(v, "join_request");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->nonce = f.Int("nonce", -kAny, kAny);
  std::memset(m->public_key, 0, sizeof(m->public_key));
  m->motion = static_cast<int8_t>(f.Int("motion", kI8Min, kI8Max));
  m->eps_s = f.Real("eps_s");
  m->delta_m = f.Real("delta_m");
  const size_t text = static_cast<size_t>(L.max_text_bytes);
  m->link_name = Strings(f, "link_name", static_cast<size_t>(L.max_join_links), text);
  const size_t n = m->link_name.size();
  if (n < 1) BadMessage(f.Path("link_name"), "a skeleton has at least one link");
  m->num_links = static_cast<int32_t>(n);
  const std::vector<int64_t> parent = Ints(f, "parent", n, kI32Min, kI32Max);
  m->parent.assign(parent.begin(), parent.end());
  m->a = RowsFrom(f, "a", n, 3);
  m->b = RowsFrom(f, "b", n, 3);
  m->radius = Reals(f, "radius", n, false);
  const size_t rules = static_cast<size_t>(L.max_ignore_rules);
  m->ignore = OptionalStrings(f, "ignore", rules, text);
  m->num_ignore = static_cast<int32_t>(m->ignore.size());
  m->ignore_entity_link = OptionalStrings(f, "ignore_entity_link", rules, text);
  m->ignore_entity = OptionalStrings(f, "ignore_entity", rules, text);
  m->ignore_entity_other_link = OptionalStrings(f, "ignore_entity_other_link", rules, text);
  const size_t k = m->ignore_entity.size();
  if (m->ignore_entity_link.size() != k || m->ignore_entity_other_link.size() != k) {
    BadMessage(f.where() + ".ignore_entity*",
               "ignore_entity_link, ignore_entity and ignore_entity_other_link differ in length");
  }
  m->num_ignore_entities = static_cast<int32_t>(k);
  std::memset(m->mac, 0, sizeof(m->mac));
  *proof = "";
  if (const nlohmann::json* p = f.Find("proof")) *proof = StringAt(*p, f.Path("proof"), 64);
}

void FromJson(const nlohmann::json& v, const WireLimits& L, tracker_pose_t* m) {
  const Fields f(v, "tracker_pose");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->session = f.Int("session", -kAny, kAny);
  m->seq = f.Int("seq", -kAny, kAny);
  const size_t n = f.Array("position", static_cast<size_t>(L.max_links)).size();
  m->num_links = static_cast<int32_t>(n);
  m->position = RowsFrom(f, "position", n, 3);
  m->orientation = RowsFrom(f, "orientation", n, 4);
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, leave_t* m) {
  const Fields f(v, "leave");
  m->utime = f.Int("utime", -kAny, kAny);
  m->client_id = f.String("client_id", static_cast<size_t>(L.max_id_bytes));
  m->session = f.Int("session", -kAny, kAny);
  std::memset(m->mac, 0, sizeof(m->mac));
}

void FromJson(const nlohmann::json& v, const WireLimits& L, object_pose_t* m) {
  const Fields f(v, "object_pose");
  m->utime = f.Int("utime", -kAny, kAny);
  m->object_id = f.String("object_id", static_cast<size_t>(L.max_id_bytes));
  m->session = f.Int("session", -kAny, kAny);
  m->seq = f.Int("seq", -kAny, kAny);
  RealsAt(f.Get("position"), f.Path("position"), 3, m->position);
  RealsAt(f.Get("orientation"), f.Path("orientation"), 4, m->orientation);
  std::memset(m->mac, 0, sizeof(m->mac));
}

}  // namespace sweptccd::ws
