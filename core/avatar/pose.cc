#include "core/avatar/pose.h"

#include <cctype>
#include <cmath>
#include <cstring>
#include <exception>
#include <istream>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/avatar/skeleton.h"
#include "core/bounded_file.h"
#include "core/json_text.h"
#include "core/utime_json.h"

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
  for (LinkPose& lp : pose->links) {
    lp.q.coeffs() /= lp.q.coeffs().stableNorm();
    FlushTinyComponents(&lp.q);
  }
  return {};
}

void FlushTinyComponents(Eigen::Quaterniond* q) {
  for (int k = 0; k < 4; ++k) {
    double& x = q->coeffs()[k];
    if (std::fabs(x) < kTinyQuaternionComponent) x = std::copysign(0.0, x);  // 0 and -0 kept.
  }
}

std::optional<Pose> ParsePoseLineAsWritten(const std::string& line, int num_links,
                                           std::string* error) {
  if (const std::string nul = NulByteProblem(line); !nul.empty()) {
    *error = "not valid JSON (" + nul + ")";
    return std::nullopt;
  }
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
  if (num_links < 0 && jl->empty()) {
    *error = "'links' is empty";
    return std::nullopt;
  }
  if (num_links >= 0 && static_cast<int64_t>(jl->size()) != num_links) {
    *error = "'links' has " + std::to_string(jl->size()) + " entries, the skeleton has " +
             std::to_string(num_links);
    return std::nullopt;
  }
  pose.links.resize(jl->size());
  for (size_t i = 0; i < jl->size(); ++i) {
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
  return pose;
}

std::optional<Pose> ParsePoseLine(const std::string& line, int num_links, std::string* error) {
  std::optional<Pose> pose = ParsePoseLineAsWritten(line, num_links, error);
  if (!pose) return std::nullopt;
  std::string problem = ValidateAndNormalizePose(&*pose, num_links);
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

uint64_t DefaultMaxPoseLineBytes(int num_links) {
  const uint64_t links = static_cast<uint64_t>(num_links < 0 ? kDefaultMaxLinks : num_links);
  return 4096 + links * 7 * 64;
}

PoseLineReader::PoseLineReader(std::istream& in, int num_links, uint64_t max_line_bytes)
    : in_(in),
      num_links_(num_links),
      max_line_bytes_(max_line_bytes > 0 ? max_line_bytes : DefaultMaxPoseLineBytes(num_links)) {}

std::optional<PoseLine> PoseLineReader::Next() {
  bool too_long = false, blank = true;
  while (in_.good() && ReadBoundedLine(in_, max_line_bytes_, &line_, &too_long, &blank)) {
    ++line_number_;
    if (blank) continue;
    PoseLine out;
    out.line_number = line_number_;
    if (too_long) {
      out.error = "longer than the cap of " + std::to_string(max_line_bytes_) +
                  " bytes for a pose of " + std::to_string(num_links_) +
                  " links (skipped to its end)";
    } else {
      out.pose = ParsePoseLineAsWritten(line_, num_links_, &out.error);
      if (out.pose && num_links_ < 0) num_links_ = static_cast<int>(out.pose->links.size());
    }
    if (!out.pose) out.error = "line " + std::to_string(line_number_) + ": " + out.error;
    return out;
  }
  return std::nullopt;
}

std::optional<PairOutcome> FeedCountedPose(PosePairer* pairer, std::optional<Pose> pose,
                                           int64_t line_number, int num_links, std::string* error) {
  if (pose) {
    const std::string problem = ValidateAndNormalizePose(&*pose, num_links);
    if (!problem.empty()) {
      *error = "line " + std::to_string(line_number) + ": " + problem;
      pose.reset();
    }
  }
  return pairer->Feed(std::move(pose), *error);
}

std::optional<PairOutcome> PoseStreamReader::Next() {
  while (std::optional<PoseLine> line = lines_.Next()) {
    std::string error = line->error;
    std::optional<PairOutcome> outcome =
        FeedCountedPose(&pairer_, std::move(line->pose), line->line_number, num_links_, &error);
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

bool SamePose(const Pose& x, const Pose& y) {
  if (x.utime != y.utime || x.links.size() != y.links.size()) return false;
  for (size_t i = 0; i < x.links.size(); ++i) {
    // Bits, not values: -0.0 and 0.0 may round on to different zeros.
    if (std::memcmp(x.links[i].p.data(), y.links[i].p.data(), 3 * sizeof(double)) != 0 ||
        std::memcmp(x.links[i].q.coeffs().data(), y.links[i].q.coeffs().data(),
                    4 * sizeof(double)) != 0) {
      return false;
    }
  }
  return true;
}

}  // namespace sweptccd
