#pragma once
// A pose as a tracker message: the one conversion of every tracker (the
// client example, `simulate-tracker`, the service benchmarks and the
// end-to-end test tools).

#include <Eigen/Core>
#include <string>

#include "core/avatar/joint_frame.h"
#include "core/avatar/pose.h"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

/// `pose` as a tracker_pose_t: its utime, num_links and, in link order, each
/// link's position and quaternion [w x y z], the numbers as they are (not
/// normalised; -0.0 stays -0.0). client_id, session and seq are the caller's
/// to set (empty, 0 and 0 here); the mac is all zero (EncodeSigned or
/// LiveClient signs).
tracker_pose_t TrackerPoseOf(const Pose& pose);
/// The same with every position moved by `offset_W` (p + offset_W).
tracker_pose_t TrackerPoseOf(const Pose& pose, const Eigen::Vector3d& offset_W);

/// One SPEC pose line `{"utime": U, "links": [[px, py, pz, qw, qx, qy, qz],
/// ...]}` as written (ParsePoseLineAsWritten: any number of links, not
/// validated) as a tracker_pose_t (TrackerPoseOf). Throws InputError with
/// the line's problem when it does not parse.
tracker_pose_t TrackerPoseOfLine(const std::string& line);

/// One frame of a tracking runtime's joint poses (docs/SKELETONS.md) as the
/// tracker_pose_t of a client that joined with `joined_links` links (-1: not
/// checked), `seq` set: the one rule of every client's PublishJointFrame
/// (LiveClient over LCM, WsLiveClient over the WebSocket door). Converts it
/// with JointSkeleton::Convert; returns "" and sets *out, else the one-line
/// reason and leaves *out alone: the frame's problem (a joint a link needs
/// not tracked, NaN, a wrong joint count, a bone off its length) or a
/// joint skeleton of another link count.
std::string TrackerPoseOfJointFrame(const JointSkeleton& joints, const JointFrame& frame,
                                    int joined_links, int64_t seq, tracker_pose_t* out);

}  // namespace sweptccd
