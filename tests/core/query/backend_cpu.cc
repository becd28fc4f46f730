#include "tests/core/query/backend_under_test.h"

namespace sweptccd::testing {

const char* BackendName() { return "cpu"; }

void AttachBackend(CcdEngine* engine) { engine->SetCuller(nullptr); }

}  // namespace sweptccd::testing
