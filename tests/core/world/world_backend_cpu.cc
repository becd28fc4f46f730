#include "tests/core/world/world_backend_under_test.h"

namespace sweptccd::testing {

const char* WorldBackendName() { return "cpu"; }

std::vector<std::unique_ptr<WorldWay>> WorldWays() { return {}; }

}  // namespace sweptccd::testing
