#pragma once
// The LCM channel names of the collision service (docs/SERVICE.md). Every
// place that spells a channel uses these; configuration may override them.

namespace sweptccd {

inline constexpr char kPoseChannel[] = "SWEPTCCD_POSE";        // tracker_pose_t, in.
inline constexpr char kContactChannel[] = "SWEPTCCD_CONTACT";  // contact_event_t, out.
inline constexpr char kRejectChannel[] = "SWEPTCCD_REJECT";    // rejection_t, out.
inline constexpr char kStatusChannel[] = "SWEPTCCD_STATUS";    // status_t, out.
inline constexpr char kJoinChannel[] = "SWEPTCCD_JOIN";              // join_request_t, in.
inline constexpr char kJoinReplyChannel[] = "SWEPTCCD_JOIN_REPLY";  // join_reply_t, out.
inline constexpr char kLeaveChannel[] = "SWEPTCCD_LEAVE";            // leave_t, in.
// The shared world (SPEC section 8, docs/SERVICE.md "Shared world").
inline constexpr char kObjectPoseChannel[] = "SWEPTCCD_OBJECT_POSE";  // object_pose_t, in.
inline constexpr char kSharedContactChannel[] = "SWEPTCCD_SHARED_CONTACT";  // shared_contact_t, out.

/// Messages LCM may hold per subscription before the handler takes them.
/// LCM's default is 30, and it drops what comes beyond: one 120 Hz tick of 64
/// clients is a burst of 64 poses (and, at every subscriber, 64 contact
/// events), so with 30 the tail of every burst was lost before any check
/// (docs/BENCHMARKS.md, "Service throughput"). Held: at most 1024 messages,
/// each one datagram (under 64 KiB: 64 MiB in all) or a message LCM
/// reassembled from fragments (its reassembly store is 16 MiB); the handlers
/// refuse an oversized message by its byte count before decoding, so the
/// queue only grows while they fall behind.
inline constexpr int kLcmQueueCapacity = 1024;

}  // namespace sweptccd
