#include "core/query/ccd_query.h"

#include <cmath>

#include "core/errors.h"
#include "core/query/environment_target.h"
#include "core/query/link_groups.h"
#include "core/query/query_run.h"

namespace sweptccd {

std::string ValidateQueryOptions(const QueryOptions& options) {
  if (!std::isfinite(options.eps_s) || !(options.eps_s > 0)) {
    return "eps must be a finite number of seconds > 0, got " + std::to_string(options.eps_s);
  }
  if (!std::isfinite(options.delta_m) || !(options.delta_m > 0)) {
    return "delta must be a finite number of metres > 0, got " + std::to_string(options.delta_m);
  }
  if (options.max_intervals < 1) return "the work limit must be at least 1 interval";
  if (options.max_candidates < 1) return "max_candidates must be at least 1";
  return {};
}

double PairDurationUs(int64_t utime0, int64_t utime1) {
  // long double holds any int64 exactly, so the difference is exact there.
  return static_cast<double>(static_cast<long double>(utime1) - static_cast<long double>(utime0));
}

namespace {

long double ExactTime(int64_t utime0, int64_t utime1, double s) {
  return static_cast<long double>(utime0) +
         static_cast<long double>(s) *
             (static_cast<long double>(utime1) - static_cast<long double>(utime0));
}

}  // namespace

double BracketTimeLo(int64_t utime0, int64_t utime1, double s) {
  const long double exact = ExactTime(utime0, utime1, s);
  double t = static_cast<double>(exact);
  if (static_cast<long double>(t) > exact) t = std::nextafter(t, -HUGE_VAL);
  return t;
}

double BracketTimeHi(int64_t utime0, int64_t utime1, double s) {
  const long double exact = ExactTime(utime0, utime1, s);
  double t = static_cast<double>(exact);
  if (static_cast<long double>(t) < exact) t = std::nextafter(t, HUGE_VAL);
  return t;
}

CcdEngine::CcdEngine(const Skeleton& skeleton, const Environment& environment,
                     CollisionFilter filter)
    : skeleton_(skeleton),
      env_(environment),
      filter_(std::move(filter)),
      groups_(std::make_shared<const internal::LinkGroups>(skeleton)) {}

QueryResult CcdEngine::Query(const Pose& pose0, const Pose& pose1,
                             const QueryOptions& options) const {
  SWEPTCCD_CHECK(pose1.utime > pose0.utime);
  SWEPTCCD_CHECK(ValidateQueryOptions(options).empty());
  internal::QueryRun run(*this, pose0, pose1, options);
  return run.Run();
}

QueryResult CcdEngine::Query(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                             const QueryOptions& options) const {
  SWEPTCCD_CHECK(pose1.utime > pose0.utime);
  SWEPTCCD_CHECK(ValidateQueryOptions(options).empty());
  SWEPTCCD_CHECK(motion.model() == options.motion && motion.num_links() == skeleton_.num_links());
  internal::QueryRun run(*this, pose0, pose1, options, &motion);
  return run.Run();
}

QueryResult CcdEngine::Query(const Pose& pose0, const Pose& pose1, const QueryOptions& options,
                             const PairClears* clears) const {
  SWEPTCCD_CHECK(pose1.utime > pose0.utime);
  SWEPTCCD_CHECK(ValidateQueryOptions(options).empty());
  SWEPTCCD_CHECK(clears == nullptr || clears->num_links() == skeleton_.num_links());
  internal::QueryRun run(*this, pose0, pose1, options, nullptr, clears);
  return run.Run();
}

QueryResult CcdEngine::Query(const PairMotion& motion, const Pose& pose0, const Pose& pose1,
                             const QueryOptions& options, const PairClears* clears) const {
  SWEPTCCD_CHECK(pose1.utime > pose0.utime);
  SWEPTCCD_CHECK(ValidateQueryOptions(options).empty());
  SWEPTCCD_CHECK(motion.model() == options.motion && motion.num_links() == skeleton_.num_links());
  SWEPTCCD_CHECK(clears == nullptr || clears->num_links() == skeleton_.num_links());
  internal::QueryRun run(*this, pose0, pose1, options, &motion, clears);
  return run.Run();
}

bool CcdEngine::TouchesAt(const PairMotion& motion, LinkIndex link, double s, double slack) const {
  return internal::EnvironmentTarget(skeleton_, env_, filter_).TouchesAt(motion, link, s, slack);
}

bool CcdEngine::Separation(const PairMotion& motion, LinkIndex link, double s, double search_radius,
                           ContactRecord* record) const {
  return internal::EnvironmentTarget(skeleton_, env_, filter_)
      .Separation(motion, link, s, search_radius, record);
}

}  // namespace sweptccd
