#include "core/avatar/pose.h"

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

namespace sweptccd {

std::string PoseProblem::Describe(int num_links) const {
  const std::string at = "link " + std::to_string(link) + ": ";
  switch (kind) {
    case Kind::kLinkCount:
      return "expected " + std::to_string(num_links) + " link poses, got " +
             std::to_string(static_cast<int64_t>(value));
    case Kind::kNonFinite:
      return at + "non-finite number";
    case Kind::kPositionOutOfRange:
      return at + "position beyond 1e9 m";
    case Kind::kZeroQuaternion:
      return at + "quaternion norm " + std::to_string(value) + " is below 1e-6";
  }
  return at + "invalid";  // Not reached: every kind is handled above.
}

namespace {

// The first problem of one link pose, or nullopt.
std::optional<PoseProblem> FindLinkProblem(const LinkPose& lp, int link) {
  PoseProblem problem;
  problem.link = link;
  const double q[4] = {lp.q.w(), lp.q.x(), lp.q.y(), lp.q.z()};
  for (int k = 0; k < 7; ++k) {
    const double v = k < 3 ? lp.p[k] : q[k - 3];
    if (!std::isfinite(v)) {
      problem.kind = PoseProblem::Kind::kNonFinite;
      problem.in_orientation = k >= 3;
      problem.component = k < 3 ? k : k - 3;
      problem.value = v;
      return problem;
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (std::fabs(lp.p[k]) > kMaxCoordinate) {
      problem.kind = PoseProblem::Kind::kPositionOutOfRange;
      problem.component = k;
      problem.value = lp.p[k];
      return problem;
    }
  }
  // stableNorm: the plain norm overflows for components near 1e200.
  const double norm = lp.q.coeffs().stableNorm();
  if (!(norm >= kMinQuaternionNorm)) {
    problem.kind = PoseProblem::Kind::kZeroQuaternion;
    problem.value = norm;
    return problem;
  }
  return std::nullopt;
}

}  // namespace

std::optional<PoseProblem> FindPoseProblem(const Pose& pose, int num_links) {
  if (static_cast<int>(pose.links.size()) != num_links) {
    PoseProblem problem;
    problem.kind = PoseProblem::Kind::kLinkCount;
    problem.value = static_cast<double>(pose.links.size());
    return problem;
  }
  for (int i = 0; i < num_links; ++i) {
    if (std::optional<PoseProblem> problem = FindLinkProblem(pose.links[i], i)) return problem;
  }
  return std::nullopt;
}

std::string ValidateAndNormalizePose(Pose* pose, int num_links) {
  if (const std::optional<PoseProblem> problem = FindPoseProblem(*pose, num_links)) {
    return problem->Describe(num_links);
  }
  for (LinkPose& lp : pose->links) lp.q.coeffs() /= lp.q.coeffs().stableNorm();
  return {};
}

namespace {

bool ReadUtime(const nlohmann::json& j, int64_t* utime) {
  if (j.is_number_integer()) {
    *utime = j.get<int64_t>();
    if (j.is_number_unsigned() && j.get<uint64_t>() > static_cast<uint64_t>(INT64_MAX)) return false;
    return true;
  }
  if (j.is_number_float()) {
    // Accept 1000000.0: integral values within the int64 range.
    const double v = j.get<double>();
    if (!std::isfinite(v) || v != std::floor(v) || std::fabs(v) >= 9.2e18) return false;
    *utime = static_cast<int64_t>(v);
    return true;
  }
  return false;
}

}  // namespace

std::optional<Pose> ParsePoseLine(const std::string& line, int num_links, std::string* error) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception& e) {
    *error = std::string("not valid JSON (") + e.what() + ")";
    return std::nullopt;
  }
  if (!doc.is_object()) {
    *error = "the line is not a JSON object";
    return std::nullopt;
  }
  Pose pose;
  auto ut = doc.find("utime");
  if (ut == doc.end() || !ReadUtime(*ut, &pose.utime)) {
    *error = "missing or non-integer 'utime'";
    return std::nullopt;
  }
  auto jl = doc.find("links");
  if (jl == doc.end() || !jl->is_array()) {
    *error = "missing 'links' array";
    return std::nullopt;
  }
  if (static_cast<int>(jl->size()) != num_links) {
    *error = "'links' has " + std::to_string(jl->size()) + " entries, the skeleton has " +
             std::to_string(num_links);
    return std::nullopt;
  }
  pose.links.resize(num_links);
  for (int i = 0; i < num_links; ++i) {
    const nlohmann::json& e = (*jl)[i];
    if (!e.is_array() || e.size() != 7) {
      *error = "link " + std::to_string(i) + ": expected [px, py, pz, qw, qx, qy, qz]";
      return std::nullopt;
    }
    double v[7];
    for (int k = 0; k < 7; ++k) {
      if (!e[k].is_number()) {
        *error = "link " + std::to_string(i) + ": entry " + std::to_string(k) + " is not a number";
        return std::nullopt;
      }
      v[k] = e[k].get<double>();
    }
    pose.links[i].p = Eigen::Vector3d(v[0], v[1], v[2]);
    pose.links[i].q = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
  }
  std::string problem = ValidateAndNormalizePose(&pose, num_links);
  if (!problem.empty()) {
    *error = problem;
    return std::nullopt;
  }
  return pose;
}

std::string PoseToJsonLine(const Pose& pose) {
  nlohmann::json doc;
  doc["utime"] = pose.utime;
  nlohmann::json links = nlohmann::json::array();
  for (const LinkPose& lp : pose.links) {
    links.push_back({lp.p.x(), lp.p.y(), lp.p.z(), lp.q.w(), lp.q.x(), lp.q.y(), lp.q.z()});
  }
  doc["links"] = links;
  return doc.dump();
}

std::optional<PairOutcome> PoseStreamReader::Next() {
  std::string line;
  while (std::getline(in_, line)) {
    ++line_number_;
    if (line.find_first_not_of(" \t\r\n\f\v") == std::string::npos) continue;  // Blank.
    std::string error;
    std::optional<Pose> pose = ParsePoseLine(line, num_links_, &error);
    if (!pose) error = "line " + std::to_string(line_number_) + ": " + error;
    std::optional<PairOutcome> outcome = pairer_.Feed(std::move(pose), error);
    if (outcome) return outcome;
    first_line_error_ = error;  // Only the first counted line yields no record.
  }
  return std::nullopt;
}

std::optional<PairOutcome> PosePairer::Feed(std::optional<Pose> pose, const std::string& error) {
  const int64_t k = lines_seen_++;
  if (k == 0) {
    if (pose) anchor_ = std::move(pose);
    return std::nullopt;
  }
  PairOutcome out;
  out.pair = k - 1;
  if (anchor_) out.utime0 = anchor_->utime;
  if (!pose) {
    out.error = "invalid pose: " + error;
    return out;
  }
  out.utime1 = pose->utime;
  if (!anchor_) {
    out.error = "no earlier valid pose to pair with";
    anchor_ = std::move(pose);  // The first valid pose anchors the stream.
    return out;
  }
  if (pose->utime <= anchor_->utime) {
    out.error = "utime " + std::to_string(pose->utime) + " is not greater than the previous " +
                "valid utime " + std::to_string(anchor_->utime);
    return out;
  }
  out.valid = true;
  out.pose0 = *anchor_;
  out.pose1 = *pose;
  anchor_ = std::move(pose);
  return out;
}

}  // namespace sweptccd
