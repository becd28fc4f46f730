#pragma once
// `sweptccd render`: PNG pictures of a contact (the scene near it, the avatar
// at both poses, the links' swept volumes, the avatar at the first contact,
// the witness and the normal) and a timeline of the whole stream (each link's
// separation against time, contacts marked), drawn through the headless EGL
// context. See docs/USAGE.md, "Pictures of a contact".

#include <string>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/geometry/mesh.h"
#include "core/query/ccd_query.h"

namespace CLI {
class App;
}

namespace sweptccd {

struct RenderCommandOptions {
  // A pair of entities of a shared world (docs/USAGE.md, "Pictures of a contact"):
  // --world with --avatar and --entity, instead of --skeleton/--poses/--env.
  std::string world_path;
  std::string avatar_id, entity_id;
  std::string skeleton_path;
  std::string poses_path;
  std::vector<std::string> env_paths;
  std::string motion = "articulated";
  QueryOptions query;
  int pair = -1;                    // -1: the first pair with contact.
  std::string out_path;             // The contact picture (PNG).
  std::string timeline_path;        // The timeline picture (PNG).
  std::string info_out;             // JSON sidecar.
  std::vector<double> eye, target;  // x y z each, or empty: automatic.
  double fov_deg = 50;
  int width = 1280, height = 720;
  std::string up;                 // "x", "y", "z" or empty: guess from the scene.
  double clip_radius_m = 4;       // Scene triangles farther from the target are not drawn.
  double max_separation_m = 0.5;  // Timeline: separations clamped here.
  int swept_steps = 12;           // In-between times drawn per link.
  MeshLoadOptions mesh;              // --max-mesh-bytes.
  int max_links = kDefaultMaxLinks;  // --max-links.
};

void AddRenderOptions(CLI::App* app, RenderCommandOptions* options);
/// 0: pictures written; 2: bad input or no contact to draw (one line on
/// stderr naming the problem); 3: no OpenGL context or out of memory.
int RunRenderCommand(const RenderCommandOptions& options);

}  // namespace sweptccd
