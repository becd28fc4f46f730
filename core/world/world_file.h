#pragma once
// The world file of SPEC section 8 ("Offline"): avatars, tracked objects and
// the static environment, with paths relative to the world file.

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry/mesh.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/world/world.h"

namespace sweptccd::world {

struct LoadedWorld {
  World world;
  Environment env;                           // The static environment (may be empty).
  std::vector<CollisionFilter> env_filters;  // Per avatar: its {"link", "object"} rules.
  /// Every file the world file names, as read: (its role, e.g. "avatars[0]
  /// ('alice') poses", and its path), so a command can refuse an output
  /// that would overwrite one.
  std::vector<std::pair<std::string, std::string>> files;
};

struct WorldLoadOptions {
  MeshLoadOptions mesh;
  int max_links = kDefaultMaxLinks;
};

/// Reads the world file and everything it names. Pose lines that are not
/// usable are not errors (SPEC 2 and 8); files that cannot be read, a
/// malformed or duplicate id, a bad motion name, an unknown link in a rule
/// are: throws InputError with one line naming the file and the problem.
LoadedWorld LoadWorldFile(const std::string& path, const WorldLoadOptions& options = {});

/// Parses one tracked-object pose line `{"utime": U, "pose": [px, py, pz,
/// qw, qx, qy, qz]}`: true and *sample (quaternion normalised) when it is
/// usable (finite, quaternion norm >= 1e-6), else false with *error.
/// The utime is read by ReadUtime (core/utime_json.h), the rule of
/// pose lines.
bool ParseObjectPoseLine(const std::string& line, RigidSample* sample, std::string* error);

/// The longest tracked-object pose line kept: 64 KiB (a utime and 7 numbers
/// need under 300 bytes); a longer line is read to its newline and not used.
inline constexpr uint64_t kMaxObjectPoseLineBytes = uint64_t{64} << 10;

/// Reads a tracked object's pose file, the one reader of `sweptccd world`
/// and `simulate-tracker --object`: line by line (ReadBoundedLine, at most
/// kMaxObjectPoseLineBytes kept), blank lines skipped, every other line
/// given to `usable` in file order when ParseObjectPoseLine accepts it.
/// Returns the number of lines not used (malformed, unusable or too long;
/// SPEC 8: not errors). Throws InputError ("PATH: ...", `what` naming the
/// file's role) when the file cannot be opened or read.
int64_t ReadObjectPoseFile(const std::string& path, const std::string& what,
                           const std::function<void(const RigidSample&)>& usable);

}  // namespace sweptccd::world
