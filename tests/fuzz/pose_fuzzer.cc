// Fuzzes ParsePoseLine (SPEC section 2). The first byte picks the skeleton's
// link count (1 to 64); the rest is the line. The contract: a pose or an
// error string; nothing thrown. A valid pose has the asked link count, unit
// quaternions, and survives PoseToJsonLine and a second parse.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "core/avatar/pose.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const int num_links = 1 + data[0] % 64;
  const std::string line = sweptccd::fuzz::AsText(data + 1, size - 1);
  std::string error;
  const std::optional<sweptccd::Pose> pose = sweptccd::ParsePoseLine(line, num_links, &error);
  if (!pose) {
    if (error.empty()) std::abort();  // A refusal must say why.
    return 0;
  }
  if (static_cast<int>(pose->links.size()) != num_links) std::abort();
  for (const sweptccd::LinkPose& l : pose->links) {
    if (std::abs(l.q.norm() - 1.0) > 1e-9) std::abort();
  }
  std::string again_error;
  if (!sweptccd::ParsePoseLine(sweptccd::PoseToJsonLine(*pose), num_links, &again_error)) {
    std::abort();  // Our own output must parse.
  }
  return 0;
}
