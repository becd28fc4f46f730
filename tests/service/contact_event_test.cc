// One record, two writers: for random query results, the contact_event_t the
// service publishes carries exactly the numbers of the JSON record
// `sweptccd query` prints (both come from MakeResultRecord).
#include "service/contact_event.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>

namespace sweptccd {
namespace {

ContactRecord RandomContact(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-2, 2);
  ContactRecord c;
  c.link = LinkIndex(static_cast<int>(rng() % 20));
  c.object = ObjectIndex(static_cast<int>(rng() % 5));
  c.triangle = static_cast<uint32_t>(rng() % 100000);
  c.s = std::uniform_real_distribution<double>(0, 1)(rng);
  c.point_link = {u(rng), u(rng), u(rng)};
  c.point_env = {u(rng), u(rng), u(rng)};
  c.normal = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
  c.separation = u(rng) * 1e-3;
  return c;
}

QueryResult RandomResult(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0, 1);
  QueryResult r;
  r.contact = rng() % 2;
  r.initially_colliding = rng() % 2;  // Also when free: the record must say false.
  r.undecided = rng() % 2;
  r.s_lo = unit(rng);
  r.s_hi = std::min(1.0, r.s_lo + unit(rng) * 1e-3);
  if (r.contact) {
    for (int i = 0, n = 1 + static_cast<int>(rng() % 3); i < n; ++i) {
      r.contacts.push_back(RandomContact(rng));
    }
  }
  for (int i = 0, n = static_cast<int>(rng() % 4); i < n; ++i) {
    LinkBracket b;
    b.link = LinkIndex(i);
    b.s_lo = unit(rng);
    b.s_hi = std::min(1.0, b.s_lo + 1e-4);
    b.initially_colliding = rng() % 2;
    b.undecided = rng() % 2;
    b.has_witness = rng() % 2;
    if (b.has_witness) b.witness = RandomContact(rng);
    r.links.push_back(b);
  }
  return r;
}

void ExpectSameContact(const contact_record_t& m, const nlohmann::json& j) {
  EXPECT_EQ(m.link, j["link"].get<int>());
  EXPECT_EQ(m.object, j["object"].get<int>());
  EXPECT_EQ(static_cast<uint32_t>(m.triangle), j["triangle"].get<uint32_t>());
  EXPECT_EQ(m.s, j["s"].get<double>());
  EXPECT_EQ(m.separation, j["separation"].get<double>());
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(m.point_link[k], j["point_link"][k].get<double>());
    EXPECT_EQ(m.point_env[k], j["point_env"][k].get<double>());
    EXPECT_EQ(m.normal[k], j["normal"][k].get<double>());
  }
}

TEST(ContactEventTest, CarriesTheNumbersOfTheCliRecord) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 500; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const QueryResult r = RandomResult(rng);
    const int64_t utime0 = 1'000'000 + static_cast<int64_t>(rng() % 1000);
    const int64_t utime1 = utime0 + 1 + static_cast<int64_t>(rng() % 100000);
    const nlohmann::json j =
        nlohmann::json::parse(ResultToJson(trial, utime0, utime1, r, true, 1.0));
    contact_event_t ev;
    FillContactEvent(MakeResultRecord(trial, utime0, utime1, r, true), &ev);
    const bool contact = j["result"] == "contact";
    // Copies: the lcm-gen constants have no out-of-line definitions.
    const int8_t expected =
        contact ? int8_t{contact_event_t::RESULT_CONTACT} : int8_t{contact_event_t::RESULT_FREE};
    EXPECT_EQ(ev.result, expected);
    EXPECT_EQ(ev.initially_colliding, j["initially_colliding"].get<bool>());
    EXPECT_EQ(ev.undecided, j["undecided"].get<bool>());
    if (!contact) {
      EXPECT_FALSE(ev.initially_colliding || ev.undecided);
    }
    if (contact) {
      EXPECT_EQ(ev.s_lo, j["s_lo"].get<double>());
      EXPECT_EQ(ev.s_hi, j["s_hi"].get<double>());
      EXPECT_EQ(ev.t_lo, j["t_lo"].get<double>());
      EXPECT_EQ(ev.t_hi, j["t_hi"].get<double>());
      ASSERT_EQ(static_cast<size_t>(ev.num_contacts), j["contacts"].size());
      for (size_t i = 0; i < ev.contacts.size(); ++i) {
        ExpectSameContact(ev.contacts[i], j["contacts"][i]);
      }
    } else {
      EXPECT_EQ(ev.num_contacts, 0);
      EXPECT_EQ(ev.s_lo, 0);
      EXPECT_EQ(ev.t_hi, 0);
    }
    ASSERT_EQ(static_cast<size_t>(ev.num_links), j["links"].size());
    for (size_t i = 0; i < ev.links.size(); ++i) {
      const nlohmann::json& l = j["links"][i];
      EXPECT_EQ(ev.links[i].link, l["link"].get<int>());
      EXPECT_EQ(ev.links[i].t_lo, l["t_lo"].get<double>());
      EXPECT_EQ(ev.links[i].t_hi, l["t_hi"].get<double>());
      EXPECT_EQ(ev.links[i].initially_colliding, l["initially_colliding"].get<bool>());
      EXPECT_EQ(ev.links[i].has_witness, l.contains("contact"));
      if (ev.links[i].has_witness) ExpectSameContact(ev.links[i].witness, l["contact"]);
    }
  }
}

TEST(ContactEventTest, InvalidClearsEveryAnswerField) {
  std::mt19937_64 rng(11);
  QueryResult r = RandomResult(rng);
  r.contact = true;
  r.contacts.push_back(RandomContact(rng));
  contact_event_t ev;
  FillContactEvent(MakeResultRecord(0, 1, 2, r, true), &ev);
  MarkContactEventInvalid("query failed: test", &ev);
  EXPECT_EQ(ev.result, int8_t{contact_event_t::RESULT_INVALID});
  EXPECT_EQ(ev.error, "query failed: test");
  EXPECT_EQ(ev.num_contacts, 0);
  EXPECT_TRUE(ev.contacts.empty());
  EXPECT_EQ(ev.num_links, 0);
  EXPECT_EQ(ev.s_lo, 0);
  EXPECT_EQ(ev.t_hi, 0);
  EXPECT_FALSE(ev.initially_colliding);
}

}  // namespace
}  // namespace sweptccd
