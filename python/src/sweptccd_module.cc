// The Python engine (`import sweptccd`): the offline query (SPEC 7) and the
// shared world (SPEC 8) of the C++ core, without a process per call. Records
// are the very JSON objects `sweptccd query` and `sweptccd world` write (the
// core builds them: MakeResultRecord/RecordToJson, WorldAnswerer::RecordJson);
// python/sweptccd/_records.py turns each into dataclasses. Input errors are
// the command's InputError messages, raised as sweptccd.InputError. The GIL
// is released while the core works; an Engine answers from several threads at
// once (CcdEngine::Query is const), a World one call at a time (its lock).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/query/ccd_query.h"
#include "core/query/query_scene.h"
#include "core/query/result_json.h"
#include "core/world/world_file.h"
#include "core/world/world_query.h"
#include "msgs/text.h"

namespace py = pybind11;

namespace sweptccd {
namespace {

using PoseArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using UtimeArray = py::array_t<int64_t, py::array::c_style | py::array::forcecast>;

QueryOptions MakeOptions(const std::string& motion, double eps, double delta, bool per_link,
                         std::optional<int64_t> max_intervals, const std::string& who) {
  QueryOptions options;
  const std::optional<MotionModel> m = ParseMotionModel(motion);
  if (!m) throw InputError(who + ": --motion must be articulated or independent");
  options.motion = *m;
  options.eps_s = eps;
  options.delta_m = delta;
  options.per_link = per_link;
  if (max_intervals) options.max_intervals = *max_intervals;  // Else the command's default.
  const std::string problem = ValidateQueryOptions(options);
  if (!problem.empty()) throw InputError(who + ": " + problem);
  return options;
}

// Row r of a (N, links, 7) array as a Pose, as written.
Pose RowPose(const double* row, int64_t utime, int num_links) {
  Pose pose;
  pose.utime = utime;
  pose.links.resize(num_links);
  for (int i = 0; i < num_links; ++i) {
    const double* v = row + 7 * i;
    pose.links[i].p = Eigen::Vector3d(v[0], v[1], v[2]);
    pose.links[i].q = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
  }
  return pose;
}

void CheckPoses(const PoseArray& poses, int num_links) {
  if (poses.ndim() != 3 || poses.shape(1) != num_links || poses.shape(2) != 7) {
    std::string shape = "(";
    for (py::ssize_t d = 0; d < poses.ndim(); ++d) {
      shape += (d ? ", " : "") + std::to_string(poses.shape(d));
    }
    throw py::value_error("poses must have shape (N, " + std::to_string(num_links) + ", 7), got " +
                          shape + (poses.ndim() == 1 ? ",)" : ")"));
  }
}

class PyEngine {
 public:
  PyEngine(const std::optional<std::string>& skeleton_path,
           const std::optional<std::string>& skeleton_json, const std::vector<std::string>& env,
           const std::string& filter_path, const std::vector<std::string>& ignore,
           const std::string& motion, double eps, double delta, bool per_link,
           std::optional<int64_t> max_intervals) {
    {
      options_ = MakeOptions(motion, eps, delta, per_link, max_intervals, "sweptccd query");
      skeleton_ =
          std::make_unique<Skeleton>(skeleton_path ? LoadSkeletonFile(*skeleton_path)
                                                   : ParseSkeletonJson(*skeleton_json, "skeleton"));
      QuerySceneSpec spec;
      spec.env_paths = env;
      spec.filter_path = filter_path;
      spec.ignore_rules = ignore;
      py::gil_scoped_release release;
      scene_ = LoadQueryScene(spec, *skeleton_, "sweptccd query");
      engine_ = std::make_unique<CcdEngine>(*skeleton_, scene_->env, std::move(scene_->filter));
    }
  }

  int num_links() const { return skeleton_->num_links(); }
  std::vector<std::string> link_names() const {
    std::vector<std::string> names;
    for (int i = 0; i < skeleton_->num_links(); ++i) {
      names.push_back(skeleton_->link(i).name);
    }
    return names;
  }
  int num_objects() const { return scene_->env.num_objects(); }
  int64_t num_triangles() const { return static_cast<int64_t>(scene_->env.num_triangles()); }

  // One SPEC 7 record (JSON text) per row after the first: the rows are a
  // pose stream, row r standing for line r + 1 of a pose file.
  std::vector<std::string> Query(const UtimeArray& utimes, const PoseArray& poses) const {
    const int n_links = num_links();
    CheckPoses(poses, n_links);
    if (utimes.ndim() != 1 || utimes.shape(0) != poses.shape(0)) {
      throw py::value_error("utimes must have shape (N,) with N = poses.shape[0] = " +
                            std::to_string(poses.shape(0)));
    }
    const int64_t n = poses.shape(0);
    const double* data = poses.data();
    const int64_t* times = utimes.data();
    std::vector<std::string> records;
    {
      py::gil_scoped_release release;
      records.reserve(n > 0 ? n - 1 : 0);
      PosePairer pairer;
      for (int64_t r = 0; r < n; ++r) {
        std::string error;
        std::optional<PairOutcome> outcome = FeedCountedPose(
            &pairer, RowPose(data + r * n_links * 7, times[r], n_links), r + 1, n_links, &error);
        if (!outcome) continue;
        if (!outcome->valid) {
          records.push_back(
              InvalidResultToJson(outcome->pair, outcome->utime0, outcome->utime1, outcome->error));
          continue;
        }
        const auto start = std::chrono::steady_clock::now();
        const QueryResult result = engine_->Query(outcome->pose0, outcome->pose1, options_);
        const double elapsed_us =
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start)
                .count();
        records.push_back(ResultToJson(outcome->pair, outcome->pose0.utime, outcome->pose1.utime,
                                       result, options_.per_link, elapsed_us));
      }
    }
    return records;
  }

  // The separation (SPEC 5) of every link at each row's pose, N x links:
  // +inf where nothing is within `search_radius` of the capsule, NaN for a
  // row whose pose is invalid.
  py::array_t<double> Separations(const PoseArray& poses, double search_radius) const {
    const int n_links = num_links();
    CheckPoses(poses, n_links);
    if (!(search_radius > 0) || !std::isfinite(search_radius)) {
      throw py::value_error("search_radius must be finite and > 0");
    }
    const int64_t n = poses.shape(0);
    py::array_t<double> out({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(n_links)});
    double* o = out.mutable_data();
    const double* data = poses.data();
    {
      py::gil_scoped_release release;
      for (int64_t r = 0; r < n; ++r) {
        Pose pose = RowPose(data + r * n_links * 7, 0, n_links);
        if (!ValidateAndNormalizePose(&pose, n_links).empty()) {
          for (int i = 0; i < n_links; ++i) o[r * n_links + i] = std::nan("");
          continue;
        }
        Pose later = pose;
        later.utime = 1;
        const PairMotion motion(*skeleton_, pose, later, options_.motion);
        for (int i = 0; i < n_links; ++i) {
          ContactRecord record;
          o[r * n_links + i] =
              engine_->Separation(motion, LinkIndex(i), 0.0, search_radius, &record)
                  ? record.separation
                  : std::numeric_limits<double>::infinity();
        }
      }
    }
    return out;
  }

 private:
  QueryOptions options_;
  std::unique_ptr<Skeleton> skeleton_;
  std::unique_ptr<QueryScene> scene_;
  std::unique_ptr<CcdEngine> engine_;
};

class PyWorld {
 public:
  PyWorld(const std::string& path, double eps, double delta, bool per_link,
          std::optional<int64_t> max_intervals) {
    {
      options_ = MakeOptions("articulated", eps, delta, per_link, max_intervals, "sweptccd world");
      py::gil_scoped_release release;
      loaded_ = std::make_unique<world::LoadedWorld>(world::LoadWorldFile(path));
      answerer_ = std::make_unique<world::WorldAnswerer>(*loaded_, options_);
    }
  }

  std::vector<std::string> avatar_ids() const {
    std::vector<std::string> ids;
    for (const auto& a : loaded_->world.avatars) ids.push_back(a.id);
    return ids;
  }

  // Every record, per avatar in world-file order, each in pair order.
  std::vector<std::string> Records() const {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);  // WorldAnswerer is not thread-safe.
    std::vector<std::string> out;
    for (world::AvatarIndex a(0); a < static_cast<int>(loaded_->world.avatars.size()); ++a) {
      for (size_t r = 0; r < loaded_->world.avatars[a].records.size(); ++r) {
        out.push_back(answerer_->RecordJson(a, r));
      }
    }
    return out;
  }

 private:
  QueryOptions options_;
  std::unique_ptr<world::LoadedWorld> loaded_;
  std::unique_ptr<world::WorldAnswerer> answerer_;
  mutable std::mutex mutex_;
};

// A joint set's skeleton and its frame conversion (docs/SKELETONS.md):
// JointSkeleton::Build and ::Convert, the rule `sweptccd skeleton` and the
// C++ client's PublishJointFrame use, so Python converts a frame exactly as
// they do.
class PyJointSkeleton {
 public:
  PyJointSkeleton(const std::string& joint_set, double height_m, const std::string& hands,
                  const std::optional<std::string>& calibration_line, double length_tolerance_m) {
    const JointSet& set = FindJointSet(joint_set);
    JointSkeletonOptions options;
    options.height_m = height_m;
    options.hands = ParseHandsOption(hands);
    options.length_tolerance_m = length_tolerance_m;
    std::optional<JointFrame> calibration;
    if (calibration_line) {
      // The line is a Python string already in memory; the reader's cap
      // still applies, as to a line of --calibrate.
      if (calibration_line->size() > MaxJointFrameLineBytes(set.num_joints())) {
        throw InputError("calibration: longer than the cap of " +
                         std::to_string(MaxJointFrameLineBytes(set.num_joints())) + " bytes");
      }
      std::string error;
      calibration = ParseJointFrameLine(*calibration_line, set.num_joints(), &error);
      if (!calibration) throw InputError("calibration: " + error);
      options.calibration = &*calibration;
    }
    try {
      joints_ = JointSkeleton::Build(set, options);
    } catch (const InputError& e) {
      throw InputError(std::string(calibration ? "calibration" : "skeleton") + ": " + e.what());
    }
  }

  int num_joints() const { return joints_.joint_set().num_joints(); }
  int num_links() const { return joints_.skeleton().num_links(); }
  std::vector<std::string> joint_names() const {
    std::vector<std::string> names;
    for (const auto& j : joints_.joint_set().joints) names.push_back(j.name);
    return names;
  }
  std::string skeleton_json() const { return SkeletonToJson(joints_.skeleton()); }

  // joints: (num_joints, 7) rows [px, py, pz, qw, qx, qy, qz]; valid: one
  // flag per joint (none: all valid). The link poses, (num_links, 7), or
  // InputError with Convert's one line.
  PoseArray Convert(const PoseArray& joints, const std::optional<std::vector<bool>>& valid,
                    int64_t utime) const {
    const int n = num_joints();
    if (joints.ndim() != 2 || joints.shape(0) != n || joints.shape(1) != 7) {
      throw py::value_error("joints must have shape (" + std::to_string(n) + ", 7)");
    }
    if (valid && static_cast<int>(valid->size()) != n) {
      throw py::value_error("valid must have " + std::to_string(n) + " flags, got " +
                            std::to_string(valid->size()));
    }
    JointFrame frame;
    frame.utime = utime;
    frame.joints.resize(n);
    const double* v = joints.data();
    for (int j = 0; j < n; ++j, v += 7) {
      frame.joints[j].p = Eigen::Vector3d(v[0], v[1], v[2]);
      frame.joints[j].q = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
      frame.joints[j].valid = !valid || (*valid)[j];
    }
    Pose pose;
    const std::string problem = joints_.Convert(frame, &pose);
    if (!problem.empty()) throw InputError(problem);
    PoseArray out({static_cast<py::ssize_t>(num_links()), static_cast<py::ssize_t>(7)});
    double* o = out.mutable_data();
    for (const LinkPose& l : pose.links) {
      const double row[7] = {l.p.x(), l.p.y(), l.p.z(), l.q.w(), l.q.x(), l.q.y(), l.q.z()};
      o = std::copy(row, row + 7, o);
    }
    return out;
  }

 private:
  JointSkeleton joints_;
};

}  // namespace
}  // namespace sweptccd

PYBIND11_MODULE(_sweptccd, m) {
  using namespace sweptccd;
  m.doc() = "SweptCCD's C++ engine; use the `sweptccd` package, not this module.";
  // The core's log lines go to standard error, as the command's do, and only
  // warnings: a notebook's output holds results, not "environment loaded".
  if (!spdlog::get("sweptccd")) {
    spdlog::set_default_logger(spdlog::stderr_color_mt("sweptccd"));
  }
  spdlog::set_level(spdlog::level::warn);
  // The command's exit-2 path prints "error: " + DisplayError(what): the same
  // line, without "error: ", is the exception's message.
  static py::exception<InputError> input_error(m, "InputError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      input_error(DisplayError(e.what()).c_str());
    }
  });
  py::class_<PyEngine>(m, "Engine")
      .def(py::init<const std::optional<std::string>&, const std::optional<std::string>&,
                    const std::vector<std::string>&, const std::string&,
                    const std::vector<std::string>&, const std::string&, double, double, bool,
                    std::optional<int64_t>>(),
           py::arg("skeleton_path"), py::arg("skeleton_json"), py::arg("env"),
           py::arg("filter_path"), py::arg("ignore"), py::arg("motion"), py::arg("eps"),
           py::arg("delta"), py::arg("per_link"), py::arg("max_intervals"))
      .def_property_readonly("num_links", &PyEngine::num_links)
      .def_property_readonly("link_names", &PyEngine::link_names)
      .def_property_readonly("num_objects", &PyEngine::num_objects)
      .def_property_readonly("num_triangles", &PyEngine::num_triangles)
      .def("query", &PyEngine::Query, py::arg("utimes"), py::arg("poses"))
      .def("separations", &PyEngine::Separations, py::arg("poses"), py::arg("search_radius"));
  py::class_<PyWorld>(m, "World")
      .def(py::init<const std::string&, double, double, bool, std::optional<int64_t>>(),
           py::arg("path"), py::arg("eps"), py::arg("delta"), py::arg("per_link"),
           py::arg("max_intervals"))
      .def_property_readonly("avatar_ids", &PyWorld::avatar_ids)
      .def("records", &PyWorld::Records);
  py::class_<PyJointSkeleton>(m, "JointSkeleton")
      .def(py::init<const std::string&, double, const std::string&,
                    const std::optional<std::string>&, double>(),
           py::arg("joint_set"), py::arg("height_m"), py::arg("hands"), py::arg("calibration_line"),
           py::arg("length_tolerance_m"))
      .def_property_readonly("num_joints", &PyJointSkeleton::num_joints)
      .def_property_readonly("num_links", &PyJointSkeleton::num_links)
      .def_property_readonly("joint_names", &PyJointSkeleton::joint_names)
      .def("skeleton_json", &PyJointSkeleton::skeleton_json)
      .def("convert", &PyJointSkeleton::Convert, py::arg("joints"), py::arg("valid"),
           py::arg("utime"));
}
