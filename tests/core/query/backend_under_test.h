#pragma once
// The backend the shared collision suites (ccd_random_test, real_data_test)
// run against. Each suite is built twice: with backend_cpu.cc (the CPU
// engine alone) and with tests/gpu/backend_gpu.cc (the GPU backend on the
// headless EGL context, llvmpipe in CI). With the GPU, every query is also
// answered by the CPU engine and the two must agree.

#include <memory>

#include "core/query/ccd_query.h"

namespace sweptccd::testing {

/// "cpu" or "gpu".
const char* BackendName();

/// Attaches the backend under test to `engine` (nothing for the CPU). Throws
/// (failing the test, never skipping it) when the GPU cannot be set up.
void AttachBackend(CcdEngine* engine);

/// The GPU backend decides with the CPU's exact tests whatever its culler did
/// not clear, so its answer equals the CPU engine's: result, flags, every
/// bracket, and each witness's link, s and separation (the triangle and
/// points may differ where several triangles are equally near).
inline bool SameAnswer(const QueryResult& a, const QueryResult& b) {
  bool same = a.contact == b.contact && a.undecided == b.undecided &&
              a.initially_colliding == b.initially_colliding && a.s_lo == b.s_lo &&
              a.s_hi == b.s_hi && a.contacts.size() == b.contacts.size() &&
              a.links.size() == b.links.size();
  for (size_t i = 0; same && i < a.contacts.size(); ++i) {
    const ContactRecord &x = a.contacts[i], &y = b.contacts[i];
    same = x.link == y.link && x.s == y.s && x.separation == y.separation;
  }
  for (size_t i = 0; same && i < a.links.size(); ++i) {
    const LinkBracket &x = a.links[i], &y = b.links[i];
    same = x.link == y.link && x.s_lo == y.s_lo && x.s_hi == y.s_hi &&
           x.undecided == y.undecided && x.initially_colliding == y.initially_colliding &&
           x.has_witness == y.has_witness &&
           (!x.has_witness ||
            (x.witness.s == y.witness.s && x.witness.separation == y.witness.separation));
  }
  return same;
}

}  // namespace sweptccd::testing
