// Fuzzes ParseJointFrameLine and JointSkeleton::Convert (docs/SKELETONS.md,
// "Joint frames"). The first byte picks the joint set and the --hands
// option; the rest is the line. The contract: a frame or an error string,
// nothing thrown; a frame converts to a pose or an error string; a
// converted pose is valid under SPEC 2 (FindPoseProblem) with one entry per
// link, and our own frame line parses again.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  using namespace sweptccd;
  static const std::vector<std::string> kIds = JointSetIds();
  const JointSet& set = FindJointSet(kIds[data[0] % kIds.size()]);
  JointSkeletonOptions options;
  options.hands = (data[0] / kIds.size()) % 2 ? HandsOption::kSimple : HandsOption::kFull;
  static std::vector<JointSkeleton> skeletons;  // Built once per (set, hands).
  const size_t slot = (data[0] % kIds.size()) * 2 + (options.hands == HandsOption::kSimple);
  if (skeletons.empty()) skeletons.resize(kIds.size() * 2);
  if (skeletons[slot].skeleton().num_links() == 0) {
    skeletons[slot] = JointSkeleton::Build(set, options);
  }
  const JointSkeleton& js = skeletons[slot];
  const std::string line = fuzz::AsText(data + 1, size - 1);
  std::string error;
  const std::optional<JointFrame> frame = ParseJointFrameLine(line, set.num_joints(), &error);
  if (!frame) {
    if (error.empty()) std::abort();  // A refusal must say why.
    return 0;
  }
  if (static_cast<int>(frame->joints.size()) != set.num_joints()) std::abort();
  std::string again;
  if (!ParseJointFrameLine(JointFrameToJsonLine(*frame), set.num_joints(), &again)) std::abort();
  Pose pose;
  const std::string problem = js.Convert(*frame, &pose);
  if (!problem.empty()) return 0;
  if (static_cast<int>(pose.links.size()) != js.skeleton().num_links()) std::abort();
  if (FindPoseProblem(pose, js.skeleton().num_links())) std::abort();
  return 0;
}
