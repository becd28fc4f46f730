#pragma once
// The LCM channel names of the collision service (docs/SERVICE.md). Every
// place that spells a channel uses these; configuration may override them.

namespace sweptccd {

inline constexpr char kPoseChannel[] = "SWEPTCCD_POSE";        // tracker_pose_t, in.
inline constexpr char kContactChannel[] = "SWEPTCCD_CONTACT";  // contact_event_t, out.
inline constexpr char kRejectChannel[] = "SWEPTCCD_REJECT";    // rejection_t, out.
inline constexpr char kStatusChannel[] = "SWEPTCCD_STATUS";    // status_t, out.

}  // namespace sweptccd
