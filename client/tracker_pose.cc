#include "sweptccd_client/tracker_pose.h"

#include <algorithm>
#include <optional>

#include "core/errors.h"

namespace sweptccd {

namespace {

// The one conversion; `offset_W` null: positions as they are.
tracker_pose_t Convert(const Pose& pose, const Eigen::Vector3d* offset_W) {
  tracker_pose_t m{};
  m.utime = pose.utime;
  m.session = 0;
  m.seq = 0;
  m.num_links = static_cast<int32_t>(pose.links.size());
  m.position.reserve(pose.links.size());
  m.orientation.reserve(pose.links.size());
  for (const LinkPose& l : pose.links) {
    const Eigen::Vector3d p_W = offset_W ? Eigen::Vector3d(l.p + *offset_W) : l.p;
    m.position.push_back({p_W.x(), p_W.y(), p_W.z()});
    m.orientation.push_back({l.q.w(), l.q.x(), l.q.y(), l.q.z()});
  }
  std::fill(std::begin(m.mac), std::end(m.mac), uint8_t{0});
  return m;
}

}  // namespace

tracker_pose_t TrackerPoseOf(const Pose& pose) { return Convert(pose, nullptr); }

tracker_pose_t TrackerPoseOf(const Pose& pose, const Eigen::Vector3d& offset_W) {
  return Convert(pose, &offset_W);
}

tracker_pose_t TrackerPoseOfLine(const std::string& line) {
  std::string error;
  const std::optional<Pose> pose = ParsePoseLineAsWritten(line, -1, &error);
  if (!pose) throw InputError("pose line: " + error);
  return TrackerPoseOf(*pose);
}

std::string TrackerPoseOfJointFrame(const JointSkeleton& joints, const JointFrame& frame,
                                    int joined_links, int64_t seq, tracker_pose_t* out) {
  const int num_links = joints.skeleton().num_links();
  if (joined_links >= 0 && joined_links != num_links) {
    return "the joint set's skeleton has " + std::to_string(num_links) +
           " links, this client joined with " + std::to_string(joined_links);
  }
  Pose pose;
  if (std::string problem = joints.Convert(frame, &pose); !problem.empty()) return problem;
  *out = TrackerPoseOf(pose);
  out->seq = seq;
  return "";
}

}  // namespace sweptccd
