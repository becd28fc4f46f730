// Fuzzes the daemon's YAML configuration (service/service_config): parse,
// then validate, as sweptccd-service does. The contract: a configuration, or
// InputError; YAML's own exceptions must be turned into InputError.

#include <cstddef>
#include <cstdint>

#include "core/errors.h"
#include "service/service_config.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const sweptccd::ServiceConfig config = sweptccd::ParseServiceConfig(
        sweptccd::fuzz::AsText(data, size), "fuzz.yaml", "/nonexistent/sweptccd-fuzz");
    sweptccd::ValidateServiceConfig(config);
  } catch (const sweptccd::InputError&) {
  }
  return 0;
}
