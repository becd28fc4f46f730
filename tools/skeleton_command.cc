#include "tools/skeleton_command.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "msgs/text.h"
#include "tools/output_paths.h"

namespace sweptccd {

void AddSkeletonOptions(CLI::App* app, SkeletonCommandOptions* o) {
  app->add_option(
         "--from", o->from,
         "Joint set: " +
             [] {
               std::string ids;
               for (const std::string& id : JointSetIds()) ids += (ids.empty() ? "" : ", ") + id;
               return ids;
             }())
      ->required()
      ->check(CLI::IsMember(JointSetIds()));
  app->add_option(
      "--height", o->height_m,
      "User's height in metres (0.5..2.5, default 1.75): scales default lengths, radii");
  app->add_option("--hands", o->hands, "none, simple (one capsule a hand) or full (default)")
      ->check(CLI::IsMember({"none", "simple", "full"}));
  app->add_option("--calibrate", o->calibrate_path,
                  "Joint frames (JSON Lines); the first sets the bone lengths and runtime radii");
  app->add_option("--out", o->out_path, "Skeleton JSON to write (SPEC 1)");
  app->add_option("--joints", o->joints_path, "Joint frames (JSON Lines) to convert");
  app->add_option("--poses-out", o->poses_out_path, "Pose stream to write (SPEC 2)");
  app->add_option("--length-tolerance", o->length_tolerance_m,
                  "Metres a frame's bone may differ from the skeleton's (default 0.01, or 5 %)");
  app->add_flag("--describe", o->describe, "Print the joints and links to standard output");
}

namespace {

// Reads joint frame lines; blank lines are skipped and not counted.
class JointFrameReader {
 public:
  JointFrameReader(std::istream& in, int num_joints)
      : in_(in), num_joints_(num_joints), cap_(MaxJointFrameLineBytes(num_joints)) {}
  // The next non-blank line: its frame, or nullopt with *error set
  // ("line N: ..."). Returns false at the end.
  bool Next(std::optional<JointFrame>* frame, std::string* error, int64_t* line_number) {
    std::string line;
    bool too_long = false, blank = true;
    while (in_.good() && ReadBoundedLine(in_, cap_, &line, &too_long, &blank)) {
      ++line_number_;
      if (blank) continue;
      *line_number = line_number_;
      error->clear();
      if (too_long) {
        *frame = std::nullopt;
        *error = "longer than the cap of " + std::to_string(cap_) + " bytes";
      } else {
        *frame = ParseJointFrameLine(line, num_joints_, error);
      }
      return true;
    }
    return false;
  }
  bool bad() const { return in_.bad(); }

 private:
  std::istream& in_;
  int num_joints_;
  uint64_t cap_;
  int64_t line_number_ = 0;
};

void Describe(const JointSkeleton& js) {
  const JointSet& set = js.joint_set();
  std::printf("%s: %s\nsource: %s\njoints: %d\n", set.id.c_str(), set.title.c_str(),
              set.source.c_str(), set.num_joints());
  for (int j = 0; j < set.num_joints(); ++j) {
    const int p = set.joints[j].parent;
    std::printf("  joint %2d %-50s parent %s%s\n", j, set.joints[j].name.c_str(),
                p < 0 ? "-" : set.joints[p].name.c_str(), js.uses_joint(j) ? "" : " (no link)");
  }
  const Skeleton& s = js.skeleton();
  std::printf("links: %d\n", s.num_links());
  for (int i = 0; i < s.num_links(); ++i) {
    const Link& l = s.link(i);
    std::printf("  link %2d %-60s parent %-3d length %.4f m radius %.4f m\n", i, l.name.c_str(),
                l.parent, l.b_L.norm(), l.radius);
  }
}

}  // namespace

int RunSkeletonCommand(const SkeletonCommandOptions& o) {
  try {
    if (o.joints_path.empty() != o.poses_out_path.empty()) {
      throw InputError("skeleton: --joints and --poses-out go together");
    }
    if (o.out_path.empty() && o.poses_out_path.empty() && !o.describe) {
      throw InputError(
          "skeleton: nothing to do: give --out, --joints with --poses-out, or --describe");
    }
    RefuseClashingPaths({{"--calibrate", o.calibrate_path}, {"--joints", o.joints_path}},
                        {{"--out", o.out_path}, {"--poses-out", o.poses_out_path}});
    const JointSet& set = FindJointSet(o.from);
    JointSkeletonOptions so;
    so.height_m = o.height_m;
    so.hands = ParseHandsOption(o.hands);
    so.length_tolerance_m = o.length_tolerance_m;
    std::optional<JointFrame> calibration;
    if (!o.calibrate_path.empty()) {
      std::ifstream in = OpenInputFile(o.calibrate_path, "calibration frame file");
      JointFrameReader reader(in, set.num_joints());
      std::string error;
      int64_t line = 0;
      if (!reader.Next(&calibration, &error, &line)) {
        throw InputError(o.calibrate_path + ": no joint frame");
      }
      if (!calibration) {
        throw InputError(o.calibrate_path + ": line " + std::to_string(line) + ": " + error);
      }
      so.calibration = &*calibration;
    }
    JointSkeleton js;
    try {
      js = JointSkeleton::Build(set, so);
    } catch (const InputError& e) {
      throw InputError((o.calibrate_path.empty() ? "skeleton" : o.calibrate_path) + ": " +
                       e.what());
    }
    if (o.describe) Describe(js);
    if (!o.out_path.empty()) {
      std::ofstream out(o.out_path, std::ios::binary | std::ios::trunc);
      out << SkeletonToJson(js.skeleton()) << '\n';
      out.flush();
      if (!out) throw InputError(o.out_path + ": cannot write the skeleton");
    }
    if (!o.joints_path.empty()) {
      std::ifstream in = OpenInputFile(o.joints_path, "joint frame file");
      std::ofstream out(o.poses_out_path, std::ios::binary | std::ios::trunc);
      if (!out) throw InputError(o.poses_out_path + ": cannot write the poses");
      JointFrameReader reader(in, set.num_joints());
      std::optional<JointFrame> frame;
      std::string error;
      int64_t line = 0, frames = 0, invalid = 0;
      while (reader.Next(&frame, &error, &line)) {
        ++frames;
        Pose pose;
        if (frame) error = js.Convert(*frame, &pose);
        if (error.empty()) {
          out << PoseToJsonLine(pose) << '\n';
          continue;
        }
        // SPEC 2: an invalid pose keeps its line (the pair numbers stay the
        // frame numbers) and is reported, never used.
        ++invalid;
        const std::string why = "line " + std::to_string(line) + ": " + error;
        nlohmann::json rec = {{"invalid", why}};
        if (frame) rec["utime"] = frame->utime;
        out << rec.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
        std::fprintf(stderr, "warning: %s: %s\n", DisplayError(o.joints_path).c_str(),
                     DisplayError(why).c_str());
      }
      if (reader.bad()) throw InputError(o.joints_path + ": read error");
      out.flush();
      if (!out) throw InputError(o.poses_out_path + ": error while writing the poses");
      spdlog::info("{}: {} frames, {} invalid", o.joints_path, frames, invalid);
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}

}  // namespace sweptccd
