#pragma once
// The world file of SPEC section 8 ("Offline"): avatars, tracked objects and
// the static environment, with paths relative to the world file.

#include <string>
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
bool ParseObjectPoseLine(const std::string& line, RigidSample* sample, std::string* error);

}  // namespace sweptccd::world
