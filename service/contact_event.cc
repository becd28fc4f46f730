#include "service/contact_event.h"

namespace sweptccd {

namespace {

void CopyVec(const Eigen::Vector3d& v, double out[3]) {
  out[0] = v.x();
  out[1] = v.y();
  out[2] = v.z();
}

contact_record_t ToMsg(const ContactRecord& c) {
  contact_record_t m;
  m.link = c.link;
  m.object = c.object;
  m.triangle = c.triangle;
  m.s = c.s;
  CopyVec(c.point_link, m.point_link);
  CopyVec(c.point_env, m.point_env);
  CopyVec(c.normal, m.normal);
  m.separation = c.separation;
  return m;
}

link_bracket_t ToMsg(const LinkRecord& l) {
  const LinkBracket& b = l.bracket;
  link_bracket_t m;
  m.link = b.link;
  m.s_lo = b.s_lo;
  m.s_hi = b.s_hi;
  m.t_lo = l.t_lo;
  m.t_hi = l.t_hi;
  m.initially_colliding = b.initially_colliding;
  m.undecided = b.undecided;
  m.has_witness = b.has_witness;
  m.witness = b.has_witness ? ToMsg(b.witness) : contact_record_t{};
  return m;
}

}  // namespace

void FillContactEvent(const ResultRecord& record, contact_event_t* event) {
  event->result = record.contact ? contact_event_t::RESULT_CONTACT : contact_event_t::RESULT_FREE;
  event->error.clear();
  event->initially_colliding = record.initially_colliding;
  event->undecided = record.undecided;
  event->s_lo = record.s_lo;
  event->s_hi = record.s_hi;
  event->t_lo = record.t_lo;
  event->t_hi = record.t_hi;
  event->contacts.clear();
  for (const ContactRecord& c : record.contacts) event->contacts.push_back(ToMsg(c));
  event->links.clear();
  for (const LinkRecord& l : record.links) event->links.push_back(ToMsg(l));
  event->num_contacts = static_cast<int32_t>(event->contacts.size());
  event->num_links = static_cast<int32_t>(event->links.size());
}

void MarkContactEventInvalid(const std::string& error, contact_event_t* event) {
  event->result = contact_event_t::RESULT_INVALID;
  event->error = error;
  event->initially_colliding = event->undecided = false;
  event->s_lo = event->s_hi = event->t_lo = event->t_hi = 0;
  event->contacts.clear();
  event->links.clear();
  event->num_contacts = 0;
  event->num_links = 0;
}

}  // namespace sweptccd
