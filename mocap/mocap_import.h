#pragma once
// Importer for Biovision BVH motion capture: turns a clip into the SPEC
// skeleton of 16 capsule links (SPEC section 1) plus one Pose per kept frame
// (SPEC section 2).
//
// Each link is ONE BVH joint. Its frame is that joint's global frame (origin
// at the joint, orientation = the joint's accumulated rotation), converted to
// metres and to the chosen up axis. a_L = 0 and b_L = the OFFSET of one chosen
// direct child joint (or End Site), scaled to metres, so every capsule is
// rigid and bone lengths stay constant. Where a limb link's chosen child is the
// joint of the next link (thigh -> shin -> foot, upper_arm -> forearm -> hand,
// pelvis -> spine -> chest), the child's A end coincides with the parent's B
// end in every frame.
//
// Joints are found by name through a table of aliases per link, compared
// case-insensitively after dropping a namespace prefix ("mixamorig:") and any
// character that is not a letter or digit. Three conventions are covered
// (see mocap_import.cc for the full table):
//   - MotionBuilder/Vicon style  Hips/Ab/Chest/Neck/Head/LeftShoulder/LeftElbow/
//     LeftWrist/LeftHip/LeftKnee/LeftAnkle/LeftToes;
//   - CMU cgspeed MotionBuilder style  Hips/LowerBack/Spine/Spine1/Neck/Neck1/
//     Head/LeftArm/LeftForeArm/LeftHand/LeftUpLeg/LeftLeg/LeftFoot/LeftToeBase;
//   - Daz/Poser style  hip/abdomen/chest/neck/head/lShldr/lForeArm/lHand/
//     lThigh/lShin/lFoot.
// Fingers, eyes, collars and other unmapped joints are skipped (they still
// take part in forward kinematics).

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"

namespace sweptccd {

/// Number of links of an imported avatar.
inline constexpr int kMocapNumLinks = 16;

/// The link names of an imported avatar, in link-index order: pelvis, spine,
/// chest, head, upper_arm_l, forearm_l, hand_l, upper_arm_r, forearm_r,
/// hand_r, thigh_l, shin_l, foot_l, thigh_r, shin_r, foot_r.
const std::vector<std::string>& MocapLinkNames();

struct MocapImportOptions {
  /// Metres per file unit, > 0; 0 = detect from the rest-pose height: among
  /// 0.01 (cm), 0.0254 (inch), 0.05644 (CMU ASF unit = 1/0.45 inch), 0.001
  /// (mm) and 1.0 (m), the one that makes the rest-pose height (vertical
  /// extent of all joints and End Sites with every rotation zero) closest to
  /// 1.6 m.
  double unit_scale_m = 0;
  /// 'y' keeps the file's Y-up world; 'z' converts to Z-up by the proper
  /// rotation (x, y, z) -> (x, -z, y). Upper case is accepted.
  char up_axis = 'y';
  /// First frame to import (0-based). -1 = auto: 1 when the file has more than
  /// one frame and frame 0 is a reference T-pose (the CMU cgspeed
  /// conversions), otherwise 0. Frame 0 counts as a reference pose when its
  /// root rotation is exactly zero but frame 1's is not, when every non-root
  /// rotation is ~0 in frame 0 but not in frame 1, or when the change from
  /// frame 0 to 1 is over 30 degrees and over 5 times the change from 1 to 2.
  int start_frame = -1;
  /// Number of file frames to cover from start_frame, before subsampling
  /// (>= 1; fewer when the clip ends first); -1 = to the end of the clip.
  int frame_count = -1;
  /// Subsampling: keep every n-th frame (n >= 1) starting at start_frame.
  int frame_step = 1;
  /// Link name -> capsule radius (metres), replacing the defaults (pelvis
  /// 0.12, spine 0.11, chest 0.13, head 0.10, upper arms 0.05, forearms 0.04,
  /// hands 0.04, thighs 0.07, shins 0.05, feet 0.045).
  std::map<std::string, double> radius_override_m;
};

struct MocapClip {
  Skeleton skeleton;  ///< kMocapNumLinks links, named as MocapLinkNames().
  /// One pose per kept frame. utime starts at 0 and is
  /// round(k * frame_time_s * 1e6) microseconds for the k-th kept frame;
  /// quaternions are unit and sign-continuous per link (dot(q_prev, q) >= 0).
  std::vector<Pose> poses;
  double frame_time_s = 0;  ///< Time between kept frames (after subsampling).
  double unit_scale_m = 0;  ///< The metres per file unit that were used.
  /// Per link, the name of the BVH joint whose global frame the link follows.
  std::vector<std::string> source_joints;
};

/// Reads and imports a BVH file, which may be gzip-compressed (by magic bytes,
/// `.gz` or not). Throws InputError("PATH: problem") for a file
/// that cannot be read, a malformed or truncated file ("PATH: line N: ..."), a
/// hierarchy in which a link's joint cannot be found, or bad options.
/// Deterministic; thread-safe (no shared state).
MocapClip ImportBvhFile(const std::string& path, const MocapImportOptions& options = {});

/// Imports BVH text. `source` names it in error messages (a path). Reads
/// exactly the number of frame lines given by "Frames:"; lines after them are
/// ignored. Throws InputError as ImportBvhFile does.
MocapClip ImportBvhText(const std::string& text, const std::string& source,
                        const MocapImportOptions& options = {});

/// Translates every pose of the clip (all link positions) by `offset_W`
/// (metres, world frame); handy to place an avatar in a scene.
/// Precondition: clip != nullptr.
void TranslateClip(MocapClip* clip, const Eigen::Vector3d& offset_W);

}  // namespace sweptccd
