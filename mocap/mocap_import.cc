#include "mocap/mocap_import.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string_view>
#include <system_error>
#include <utility>

#include "core/errors.h"
#include "core/geometry/mesh.h"

namespace sweptccd {
namespace {

// ---------------------------------------------------------------------------
// BVH text -> joints, channels and frame values.

enum class Channel { kXposition, kYposition, kZposition, kXrotation, kYrotation, kZrotation };

struct BvhJoint {
  std::string name;  // "End Site" for end sites.
  bool end_site = false;
  int parent = -1;
  int line = 0;  // Line of the ROOT/JOINT/End Site keyword.
  bool has_offset = false;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // File units, parent frame.
  bool has_channels = false;
  std::vector<Channel> channels;
  int first_channel = 0;  // Index of channels[0] in a frame line.
  std::vector<int> children;
};

struct BvhData {
  std::vector<BvhJoint> joints;  // Depth-first file order: parents before children.
  int num_channels = 0;
  int64_t num_frames = 0;
  double frame_time_s = 0;
  std::vector<double> values;  // num_frames rows of num_channels values.

  double value(int64_t frame, int channel) const {
    return values[static_cast<size_t>(frame) * num_channels + channel];
  }
};

// Limits that keep a hostile file from exhausting memory.
constexpr int kMaxChannelsPerJoint = 32;
constexpr int64_t kMaxFrames = std::numeric_limits<int32_t>::max();

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

char ToLower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

bool EqualsIgnoreCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (ToLower(a[i]) != ToLower(b[i])) return false;
  }
  return true;
}

bool StartsWithIgnoreCase(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() && EqualsIgnoreCase(text.substr(0, prefix.size()), prefix);
}

// A token for an error message: clipped, non-printable bytes replaced.
std::string Quote(std::string_view token) {
  constexpr size_t kMax = 40;
  std::string out = "'";
  for (size_t i = 0; i < token.size() && i < kMax; ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (token.size() > kMax) out += "...";
  return out + "'";
}

// Parses a whole token as a finite double (locale-independent).
bool ParseDouble(std::string_view token, double* value) {
  if (token.size() > 1 && token[0] == '+') token.remove_prefix(1);
  if (token.empty() || token[0] == '+') return false;
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, *value, std::chars_format::general);
  return ec == std::errc() && ptr == end && std::isfinite(*value);
}

bool ParseInt64(std::string_view token, int64_t* value) {
  if (token.size() > 1 && token[0] == '+') token.remove_prefix(1);
  if (token.empty() || token[0] == '+') return false;
  const char* end = token.data() + token.size();
  auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  return ec == std::errc() && ptr == end;
}

bool ParseChannel(std::string_view token, Channel* channel) {
  static const std::array<std::pair<const char*, Channel>, 6> kNames = {{
      {"Xposition", Channel::kXposition},
      {"Yposition", Channel::kYposition},
      {"Zposition", Channel::kZposition},
      {"Xrotation", Channel::kXrotation},
      {"Yrotation", Channel::kYrotation},
      {"Zrotation", Channel::kZrotation},
  }};
  for (const auto& [name, value] : kNames) {
    if (EqualsIgnoreCase(token, name)) {
      *channel = value;
      return true;
    }
  }
  return false;
}

bool IsRotation(Channel c) {
  return c == Channel::kXrotation || c == Channel::kYrotation || c == Channel::kZrotation;
}

// Whitespace tokenizer over the whole text that knows line numbers.
class Lexer {
 public:
  Lexer(std::string_view text, const std::string& source) : text_(text), source_(source) {
    // A UTF-8 byte order mark is not part of the first keyword.
    if (text_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;
  }

  // The next token, crossing line ends; empty at the end of the text.
  std::string_view Next() {
    while (pos_ < text_.size() && (IsSpace(text_[pos_]) || text_[pos_] == '\n')) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    token_line_ = line_;
    const size_t begin = pos_;
    while (pos_ < text_.size() && !IsSpace(text_[pos_]) && text_[pos_] != '\n') ++pos_;
    return text_.substr(begin, pos_ - begin);
  }

  // The rest of the current line, trimmed; the line end is not consumed.
  std::string_view RestOfLine() {
    while (pos_ < text_.size() && IsSpace(text_[pos_])) ++pos_;
    const size_t begin = pos_;
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    size_t end = pos_;
    while (end > begin && IsSpace(text_[end - 1])) --end;
    return text_.substr(begin, end - begin);
  }

  // Moves to the next line that holds more than whitespace and returns it
  // (without its line end); false at the end of the text. Call only after the
  // rest of the current line has been consumed.
  bool NextNonBlankLine(std::string_view* line) {
    while (pos_ < text_.size()) {
      if (text_[pos_] == '\n') {
        ++line_;
        ++pos_;
      }
      const size_t begin = pos_;
      while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
      const std::string_view candidate = text_.substr(begin, pos_ - begin);
      if (std::any_of(candidate.begin(), candidate.end(), [](char c) { return !IsSpace(c); })) {
        token_line_ = line_;
        *line = candidate;
        return true;
      }
    }
    token_line_ = line_;
    return false;
  }

  int line() const { return token_line_; }

  [[noreturn]] void Fail(const std::string& problem) const {
    throw InputError(source_ + ": line " + std::to_string(token_line_) + ": " + problem);
  }

 private:
  std::string_view text_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_ = 1;
  int token_line_ = 1;
};

std::string JointLabel(const BvhJoint& joint) {
  if (joint.end_site) return "End Site (line " + std::to_string(joint.line) + ")";
  return "joint " + Quote(joint.name);
}

// Reads the name after ROOT/JOINT (rest of the line) and the opening brace.
std::string ReadJointName(Lexer* lexer, const char* keyword) {
  std::string_view name = lexer->RestOfLine();
  bool brace = false;
  if (!name.empty() && name.back() == '{') {
    brace = true;
    name.remove_suffix(1);
    while (!name.empty() && IsSpace(name.back())) name.remove_suffix(1);
  }
  if (name.empty()) lexer->Fail(std::string(keyword) + " without a name");
  if (!brace) {
    const std::string_view token = lexer->Next();
    if (token != "{") {
      lexer->Fail("expected '{' after " + std::string(keyword) + " " + Quote(name) + ", got " +
                  (token.empty() ? std::string("the end of the file") : Quote(token)));
    }
  }
  return std::string(name);
}

// Reads "Frames:" / "Frame Time:" style labels, tolerant of the colon being
// attached or separate, and returns the value token that follows.
std::string_view ReadLabeledValue(Lexer* lexer, std::string_view first_word,
                                  std::string_view second_word, const char* what) {
  std::string_view token = lexer->Next();
  std::string_view rest;
  if (second_word.empty()) {
    if (!StartsWithIgnoreCase(token, first_word)) {
      lexer->Fail(std::string("expected '") + what + "' after MOTION, got " +
                  (token.empty() ? std::string("the end of the file") : Quote(token)));
    }
    rest = token.substr(first_word.size());
  } else {
    if (!EqualsIgnoreCase(token, first_word)) {
      lexer->Fail(std::string("expected '") + what + "', got " +
                  (token.empty() ? std::string("the end of the file") : Quote(token)));
    }
    token = lexer->Next();
    if (!StartsWithIgnoreCase(token, second_word)) {
      lexer->Fail(std::string("expected '") + what + "', got " +
                  (token.empty() ? std::string("the end of the file") : Quote(token)));
    }
    rest = token.substr(second_word.size());
  }
  if (rest.empty()) rest = lexer->Next();
  if (rest == ":") rest = lexer->Next();
  if (!rest.empty() && rest[0] == ':') rest.remove_prefix(1);
  if (rest.empty()) lexer->Fail(std::string("'") + what + "' has no value");
  return rest;
}

BvhData ParseBvh(std::string_view text, const std::string& source) {
  Lexer lexer(text, source);
  BvhData bvh;
  std::string_view token = lexer.Next();
  if (token.empty()) lexer.Fail("the file is empty (expected HIERARCHY)");
  if (!EqualsIgnoreCase(token, "HIERARCHY")) {
    lexer.Fail("expected HIERARCHY, got " + Quote(token) + " (not a BVH file?)");
  }
  token = lexer.Next();
  if (!EqualsIgnoreCase(token, "ROOT")) {
    lexer.Fail("expected ROOT after HIERARCHY, got " +
               (token.empty() ? std::string("the end of the file") : Quote(token)));
  }
  {
    BvhJoint root;
    root.line = lexer.line();
    root.name = ReadJointName(&lexer, "ROOT");
    bvh.joints.push_back(std::move(root));
  }
  std::vector<int> open = {0};  // Joints whose '{' is not closed yet.
  while (!open.empty()) {
    const int current = open.back();
    token = lexer.Next();
    if (token.empty()) {
      lexer.Fail("the file ends inside the HIERARCHY (" + JointLabel(bvh.joints[current]) +
                 " is not closed; truncated file?)");
    }
    if (EqualsIgnoreCase(token, "OFFSET")) {
      if (bvh.joints[current].has_offset) {
        lexer.Fail("second OFFSET in " + JointLabel(bvh.joints[current]));
      }
      Eigen::Vector3d offset;
      for (int k = 0; k < 3; ++k) {
        const std::string_view number = lexer.Next();
        if (!ParseDouble(number, &offset[k])) {
          lexer.Fail("OFFSET of " + JointLabel(bvh.joints[current]) +
                     " needs 3 finite numbers, got " +
                     (number.empty() ? std::string("the end of the file") : Quote(number)));
        }
      }
      bvh.joints[current].offset = offset;
      bvh.joints[current].has_offset = true;
    } else if (EqualsIgnoreCase(token, "CHANNELS")) {
      BvhJoint& joint = bvh.joints[current];
      if (joint.end_site) lexer.Fail("an End Site cannot have CHANNELS");
      if (joint.has_channels) lexer.Fail("second CHANNELS in " + JointLabel(joint));
      const std::string_view count_token = lexer.Next();
      int64_t count = 0;
      if (!ParseInt64(count_token, &count) || count < 0 || count > kMaxChannelsPerJoint) {
        lexer.Fail("CHANNELS of " + JointLabel(joint) + " needs a channel count in [0, " +
                   std::to_string(kMaxChannelsPerJoint) + "], got " + Quote(count_token));
      }
      joint.has_channels = true;
      joint.first_channel = bvh.num_channels;
      for (int64_t k = 0; k < count; ++k) {
        const std::string_view name = lexer.Next();
        Channel channel;
        if (!ParseChannel(name, &channel)) {
          lexer.Fail("CHANNELS of " + JointLabel(joint) + " declares " + std::to_string(count) +
                     " channels but name " + std::to_string(k + 1) + " is " +
                     (name.empty() ? std::string("the end of the file") : Quote(name)) +
                     " (expected Xposition, Yposition, Zposition, Xrotation, Yrotation or "
                     "Zrotation)");
        }
        joint.channels.push_back(channel);
      }
      bvh.num_channels += static_cast<int>(count);
    } else if (EqualsIgnoreCase(token, "JOINT")) {
      if (bvh.joints[current].end_site) lexer.Fail("an End Site cannot have child joints");
      BvhJoint joint;
      joint.line = lexer.line();
      joint.name = ReadJointName(&lexer, "JOINT");
      joint.parent = current;
      bvh.joints[current].children.push_back(static_cast<int>(bvh.joints.size()));
      open.push_back(static_cast<int>(bvh.joints.size()));
      bvh.joints.push_back(std::move(joint));
    } else if (EqualsIgnoreCase(token, "End")) {
      if (bvh.joints[current].end_site) lexer.Fail("an End Site cannot have an End Site");
      BvhJoint site;
      site.line = lexer.line();
      token = lexer.Next();
      if (EqualsIgnoreCase(token, "Site{")) {
        // "End Site{" written without a space.
      } else if (!EqualsIgnoreCase(token, "Site")) {
        lexer.Fail("expected 'Site' after 'End', got " +
                   (token.empty() ? std::string("the end of the file") : Quote(token)));
      } else {
        token = lexer.Next();
        if (token != "{") {
          lexer.Fail("expected '{' after End Site, got " +
                     (token.empty() ? std::string("the end of the file") : Quote(token)));
        }
      }
      site.name = "End Site";
      site.end_site = true;
      site.parent = current;
      bvh.joints[current].children.push_back(static_cast<int>(bvh.joints.size()));
      open.push_back(static_cast<int>(bvh.joints.size()));
      bvh.joints.push_back(std::move(site));
    } else if (token == "}") {
      if (!bvh.joints[current].has_offset) {
        lexer.Fail(JointLabel(bvh.joints[current]) + " has no OFFSET");
      }
      open.pop_back();
    } else {
      Channel channel;
      if (ParseChannel(token, &channel)) {
        lexer.Fail("channel name " + Quote(token) + " outside CHANNELS in " +
                   JointLabel(bvh.joints[current]) +
                   " (CHANNELS declares fewer channels than it lists?)");
      }
      lexer.Fail("unexpected " + Quote(token) + " in " + JointLabel(bvh.joints[current]) +
                 (EqualsIgnoreCase(token, "MOTION") ? " (a '}' is missing)" : ""));
    }
  }

  token = lexer.Next();
  if (EqualsIgnoreCase(token, "ROOT")) lexer.Fail("a second ROOT is not supported");
  if (token.empty()) lexer.Fail("the MOTION section is missing (truncated file?)");
  if (!EqualsIgnoreCase(token, "MOTION")) {
    lexer.Fail("expected MOTION after the HIERARCHY, got " + Quote(token));
  }
  if (bvh.num_channels == 0) lexer.Fail("the HIERARCHY declares no CHANNELS");

  std::string_view value = ReadLabeledValue(&lexer, "Frames", "", "Frames:");
  if (!ParseInt64(value, &bvh.num_frames) || bvh.num_frames < 1 || bvh.num_frames > kMaxFrames) {
    lexer.Fail("'Frames:' needs a frame count in [1, " + std::to_string(kMaxFrames) + "], got " +
               Quote(value));
  }
  value = ReadLabeledValue(&lexer, "Frame", "Time", "Frame Time:");
  if (!ParseDouble(value, &bvh.frame_time_s) || !(bvh.frame_time_s > 0)) {
    lexer.Fail("'Frame Time:' needs a positive number of seconds, got " + Quote(value));
  }
  const std::string_view trailing = lexer.RestOfLine();
  if (!trailing.empty()) lexer.Fail("unexpected " + Quote(trailing) + " after the frame time");

  // Reserve no more than the text could possibly hold (2 bytes per value).
  const size_t wanted = static_cast<size_t>(bvh.num_frames) * bvh.num_channels;
  bvh.values.reserve(std::min(wanted, text.size() / 2 + 1));
  for (int64_t frame = 0; frame < bvh.num_frames; ++frame) {
    std::string_view line;
    if (!lexer.NextNonBlankLine(&line)) {
      lexer.Fail("truncated MOTION section: 'Frames:' says " + std::to_string(bvh.num_frames) +
                 " frames but only " + std::to_string(frame) + " frame lines follow");
    }
    int count = 0;
    size_t pos = 0;
    while (true) {
      while (pos < line.size() && IsSpace(line[pos])) ++pos;
      if (pos >= line.size()) break;
      const size_t begin = pos;
      while (pos < line.size() && !IsSpace(line[pos])) ++pos;
      const std::string_view number = line.substr(begin, pos - begin);
      if (count == bvh.num_channels) {
        lexer.Fail("frame " + std::to_string(frame) + " has more than " +
                   std::to_string(bvh.num_channels) + " values (one per channel)");
      }
      double v = 0;
      if (!ParseDouble(number, &v)) {
        lexer.Fail("frame " + std::to_string(frame) + ", value " + std::to_string(count + 1) +
                   ": " + Quote(number) + " is not a finite number");
      }
      bvh.values.push_back(v);
      ++count;
    }
    if (count != bvh.num_channels) {
      lexer.Fail("frame " + std::to_string(frame) + " has " + std::to_string(count) +
                 " values, expected " + std::to_string(bvh.num_channels) +
                 " (one per channel; truncated line?)");
    }
  }
  // Lines after the announced frames are ignored (some exporters write one
  // more frame than they announce).
  return bvh;
}

// ---------------------------------------------------------------------------
// The avatar: which BVH joint each link follows.

struct LinkSpec {
  const char* name;
  int parent;
  double radius_m;
  int side;  // 0: trunk; 1: left; 2: right (aliases starting with '%' get a side).
  std::vector<const char*> joint_aliases;  // Normalised names, best first.
  std::vector<const char*> end_aliases;    // Preferred children for b, best first.
  int chain_next;                          // Link whose joint is the preferred child for b, or -1.
  // When the chosen child sits at zero offset (same origin), the link follows
  // that child instead and looks again (CMU: Hips -> LowerBack, Spine1 -> Neck).
  bool collapse_zero_offset;
  double fallback_length_m;  // b length when no child with a non-zero offset exists.
};

enum LinkIndex {
  kPelvis,
  kSpine,
  kChest,
  kHead,
  kUpperArmL,
  kForearmL,
  kHandL,
  kUpperArmR,
  kForearmR,
  kHandR,
  kThighL,
  kShinL,
  kFootL,
  kThighR,
  kShinR,
  kFootR,
};

const std::vector<LinkSpec>& LinkSpecs() {
  // Aliases are compared with NormalizeName(joint name). '%' stands for the
  // side, as a prefix ("left", "l") or suffix ("left", "l").
  static const std::vector<const char*> kUpperArm = {"%arm", "%upperarm", "%shldr", "%uparm",
                                                     "%shoulder"};
  static const std::vector<const char*> kForearm = {"%forearm", "%lowerarm", "%elbow"};
  static const std::vector<const char*> kHand = {"%hand", "%wrist"};
  static const std::vector<const char*> kHandEnd = {"%mid1",          "%middle1", "%handmiddle1",
                                                    "%middlefinger1", "%handend", "%handtip"};
  static const std::vector<const char*> kThigh = {"%upleg", "%thigh", "%upperleg", "%hip"};
  static const std::vector<const char*> kShin = {"%leg", "%shin", "%lowerleg", "%knee", "%calf"};
  static const std::vector<const char*> kFoot = {"%foot", "%ankle"};
  static const std::vector<const char*> kFootEnd = {"%toebase", "%toes", "%toe", "%ball"};
  static const std::vector<LinkSpec> kSpecs = {
      {"pelvis",
       -1,
       0.12,
       0,
       {"hips", "hip", "pelvis", "root"},
       {"ab", "abdomen", "lowerback", "spine", "spine0"},
       kSpine,
       true,
       0.10},
      {"spine",
       kPelvis,
       0.11,
       0,
       {"ab", "abdomen", "abdomenlower", "spine", "spine0", "torso"},
       {"chest", "spine1", "spine2", "abdomenupper", "chestlower"},
       kChest,
       true,
       0.10},
      {"chest",
       kSpine,
       0.13,
       0,
       {"chest", "upperchest", "chestupper", "spine2", "spine1", "thorax"},
       {"neck", "neck1", "lowerneck", "necklower"},
       kHead,
       true,
       0.10},
      {"head",
       kChest,
       0.10,
       0,
       {"head", "skull"},
       {"headend", "headtop", "headtopend", "headnub", "headsite"},
       -1,
       false,
       0.15},
      {"upper_arm_l", kChest, 0.05, 1, kUpperArm, {}, kForearmL, false, 0.10},
      {"forearm_l", kUpperArmL, 0.04, 1, kForearm, {}, kHandL, false, 0.10},
      {"hand_l", kForearmL, 0.04, 1, kHand, kHandEnd, -1, false, 0.08},
      {"upper_arm_r", kChest, 0.05, 2, kUpperArm, {}, kForearmR, false, 0.10},
      {"forearm_r", kUpperArmR, 0.04, 2, kForearm, {}, kHandR, false, 0.10},
      {"hand_r", kForearmR, 0.04, 2, kHand, kHandEnd, -1, false, 0.08},
      {"thigh_l", kPelvis, 0.07, 1, kThigh, {}, kShinL, false, 0.10},
      {"shin_l", kThighL, 0.05, 1, kShin, {}, kFootL, false, 0.10},
      {"foot_l", kShinL, 0.045, 1, kFoot, kFootEnd, -1, false, 0.10},
      {"thigh_r", kPelvis, 0.07, 2, kThigh, {}, kShinR, false, 0.10},
      {"shin_r", kThighR, 0.05, 2, kShin, {}, kFootR, false, 0.10},
      {"foot_r", kShinR, 0.045, 2, kFoot, kFootEnd, -1, false, 0.10},
  };
  return kSpecs;
}

// Lower case, namespace prefix ("mixamorig:") dropped, letters and digits only.
std::string NormalizeName(std::string_view name) {
  const size_t colon = name.rfind(':');
  if (colon != std::string_view::npos) name.remove_prefix(colon + 1);
  std::string out;
  for (char c : name) {
    const char lower = ToLower(c);
    if ((lower >= 'a' && lower <= 'z') || (lower >= '0' && lower <= '9')) out += lower;
  }
  return out;
}

// The concrete names an alias stands for on `side`.
std::vector<std::string> ExpandAlias(const char* alias, int side) {
  const std::string_view a(alias);
  if (a.empty() || a[0] != '%') return {std::string(a)};
  const std::string stem(a.substr(1));
  const char* long_side = side == 1 ? "left" : "right";
  const char* short_side = side == 1 ? "l" : "r";
  return {long_side + stem, short_side + stem, stem + long_side, stem + short_side};
}

// Index of the first joint (not End Site) whose name matches one of `aliases`,
// in alias order; -1 if none. With `among` set, only those joints count.
int FindJoint(const BvhData& bvh, const std::vector<const char*>& aliases, int side,
              const std::vector<int>* among) {
  for (const char* alias : aliases) {
    for (const std::string& name : ExpandAlias(alias, side)) {
      if (among != nullptr) {
        for (int j : *among) {
          if (!bvh.joints[j].end_site && NormalizeName(bvh.joints[j].name) == name) return j;
        }
      } else {
        for (size_t j = 0; j < bvh.joints.size(); ++j) {
          if (!bvh.joints[j].end_site && NormalizeName(bvh.joints[j].name) == name) {
            return static_cast<int>(j);
          }
        }
      }
    }
  }
  return -1;
}

// Direction of the bone that ends at `joint` in the rest pose (all rotations
// zero, so also in the joint's own frame): its OFFSET, or the first non-zero
// OFFSET further up; +Y (the file's up) when there is none.
Eigen::Vector3d RestBoneDirection(const BvhData& bvh, int joint) {
  for (int k = joint; k != -1; k = bvh.joints[k].parent) {
    const double n = bvh.joints[k].offset.norm();
    if (n > 0) return bvh.joints[k].offset / n;
  }
  return Eigen::Vector3d::UnitY();
}

struct LinkBinding {
  int joint = -1;
  Eigen::Vector3d b_L = Eigen::Vector3d::Zero();  // Metres, in the joint frame.
};

std::string AliasList(const LinkSpec& spec) {
  std::string out;
  for (const char* alias : spec.joint_aliases) {
    for (const std::string& name : ExpandAlias(alias, spec.side)) {
      if (!out.empty()) out += ", ";
      out += name;
    }
  }
  return out;
}

std::vector<LinkBinding> BindLinks(const BvhData& bvh, double unit_scale_m,
                                   const std::string& source) {
  const std::vector<LinkSpec>& specs = LinkSpecs();
  std::vector<int> found(specs.size(), -1);
  for (size_t i = 0; i < specs.size(); ++i) {
    found[i] = FindJoint(bvh, specs[i].joint_aliases, specs[i].side, nullptr);
    if (found[i] < 0) {
      throw InputError(
          source + ": no BVH joint found for link '" + specs[i].name +
          "' (looked for a joint named, ignoring case and '_': " + AliasList(specs[i]) + ")");
    }
  }
  // Offsets below 0.1 mm count as zero (End Sites written as 0 0 0).
  const double tiny_offset = 1e-4 / unit_scale_m;
  std::vector<LinkBinding> bindings(specs.size());
  for (size_t i = 0; i < specs.size(); ++i) {
    const LinkSpec& spec = specs[i];
    int joint = found[i];
    int end = -1;
    for (size_t guard = 0; guard <= bvh.joints.size(); ++guard) {
      const std::vector<int>& children = bvh.joints[joint].children;
      std::vector<int> candidates;
      if (spec.chain_next >= 0) {
        const int next = found[spec.chain_next];
        if (std::find(children.begin(), children.end(), next) != children.end()) {
          candidates.push_back(next);
        }
      }
      for (const char* alias : spec.end_aliases) {
        const int c = FindJoint(bvh, {alias}, spec.side, &children);
        if (c >= 0) candidates.push_back(c);
      }
      for (int c : children) {
        if (bvh.joints[c].end_site) candidates.push_back(c);
      }
      int collapse_to = -1;
      for (int c : candidates) {
        if (bvh.joints[c].offset.norm() > tiny_offset) {
          end = c;
          break;
        }
        if (collapse_to < 0 && spec.collapse_zero_offset && !bvh.joints[c].end_site &&
            !bvh.joints[c].children.empty()) {
          collapse_to = c;
        }
      }
      if (end >= 0 || collapse_to < 0) break;
      joint = collapse_to;  // Same origin; follow it and look again.
    }
    bindings[i].joint = joint;
    if (end >= 0) {
      bindings[i].b_L = unit_scale_m * bvh.joints[end].offset;
    } else {
      bindings[i].b_L = spec.fallback_length_m * RestBoneDirection(bvh, joint);
    }
  }
  for (size_t i = 0; i < specs.size(); ++i) {
    for (size_t k = 0; k < i; ++k) {
      if (bindings[i].joint == bindings[k].joint) {
        throw InputError(source + ": BVH joint " + Quote(bvh.joints[bindings[i].joint].name) +
                         " matches both link '" + specs[k].name + "' and link '" + specs[i].name +
                         "'");
      }
    }
  }
  return bindings;
}

// ---------------------------------------------------------------------------
// Units, start frame, forward kinematics.

double DetectUnitScale(const BvhData& bvh) {
  std::vector<Eigen::Vector3d> rest(bvh.joints.size());
  double min_y = std::numeric_limits<double>::infinity();
  double max_y = -min_y;
  for (size_t j = 0; j < bvh.joints.size(); ++j) {
    const int parent = bvh.joints[j].parent;
    rest[j] = (parent < 0 ? Eigen::Vector3d::Zero() : rest[parent]) + bvh.joints[j].offset;
    min_y = std::min(min_y, rest[j].y());
    max_y = std::max(max_y, rest[j].y());
  }
  const double height = max_y - min_y;
  constexpr std::array<double, 5> kCandidates = {0.01, 0.0254, 0.05644, 0.001, 1.0};
  constexpr double kTargetHeightM = 1.6;
  double best = kCandidates[0];
  for (double scale : kCandidates) {
    if (std::abs(height * scale - kTargetHeightM) < std::abs(height * best - kTargetHeightM)) {
      best = scale;
    }
  }
  return best;
}

double WrappedDegrees(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return std::min(d, 360.0 - d);
}

// Largest change of any rotation channel between two frames (degrees).
double MaxRotationChange(const BvhData& bvh, int64_t f0, int64_t f1) {
  double change = 0;
  for (const BvhJoint& joint : bvh.joints) {
    for (size_t k = 0; k < joint.channels.size(); ++k) {
      if (!IsRotation(joint.channels[k])) continue;
      const int c = joint.first_channel + static_cast<int>(k);
      change = std::max(change, WrappedDegrees(bvh.value(f0, c), bvh.value(f1, c)));
    }
  }
  return change;
}

// Largest |rotation| of frame f, over the root (root = true) or the other joints.
double MaxRotation(const BvhData& bvh, int64_t f, bool root) {
  double largest = 0;
  for (size_t j = 0; j < bvh.joints.size(); ++j) {
    if ((j == 0) != root) continue;
    const BvhJoint& joint = bvh.joints[j];
    for (size_t k = 0; k < joint.channels.size(); ++k) {
      if (!IsRotation(joint.channels[k])) continue;
      const int c = joint.first_channel + static_cast<int>(k);
      largest = std::max(largest, WrappedDegrees(bvh.value(f, c), 0.0));
    }
  }
  return largest;
}

bool FrameZeroIsReferencePose(const BvhData& bvh) {
  if (bvh.num_frames < 2) return false;
  // CMU cgspeed conversions: frame 0 has exactly zero root rotation.
  const bool root_has_rotation =
      std::any_of(bvh.joints[0].channels.begin(), bvh.joints[0].channels.end(), IsRotation);
  if (root_has_rotation && MaxRotation(bvh, 0, true) == 0 && MaxRotation(bvh, 1, true) > 0) {
    return true;
  }
  // Every non-root joint at ~0 degrees in frame 0 but not in frame 1.
  if (MaxRotation(bvh, 0, false) < 0.01 && MaxRotation(bvh, 1, false) > 1.0) return true;
  // Frame 0 differs strongly from frame 1 compared with the next step.
  if (bvh.num_frames >= 3) {
    const double d01 = MaxRotationChange(bvh, 0, 1);
    const double d12 = MaxRotationChange(bvh, 1, 2);
    if (d01 > 30.0 && d01 > 5.0 * d12) return true;
  }
  return false;
}

Eigen::Matrix3d AxisRotation(Channel channel, double degrees) {
  constexpr double kRadiansPerDegree = 3.14159265358979323846 / 180.0;
  const double r = degrees * kRadiansPerDegree;
  const double c = std::cos(r);
  const double s = std::sin(r);
  Eigen::Matrix3d m;
  switch (channel) {
    case Channel::kXrotation:
      m << 1, 0, 0, 0, c, -s, 0, s, c;
      break;
    case Channel::kYrotation:
      m << c, 0, s, 0, 1, 0, -s, 0, c;
      break;
    default:
      m << c, -s, 0, s, c, 0, 0, 0, 1;
      break;
  }
  return m;
}

// Global frames (file units, file axes) of every joint for one frame:
// X_W,joint = X_W,parent * translate(offset + position channels) * R, where R
// is the product of the rotation channels in the order they are listed.
void ForwardKinematics(const BvhData& bvh, int64_t frame, std::vector<Eigen::Matrix3d>* R_WJ,
                       std::vector<Eigen::Vector3d>* p_WJ) {
  const size_t n = bvh.joints.size();
  R_WJ->resize(n);
  p_WJ->resize(n);
  for (size_t j = 0; j < n; ++j) {
    const BvhJoint& joint = bvh.joints[j];
    Eigen::Vector3d t = joint.offset;
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    for (size_t k = 0; k < joint.channels.size(); ++k) {
      const double v = bvh.value(frame, joint.first_channel + static_cast<int>(k));
      switch (joint.channels[k]) {
        case Channel::kXposition:
          t.x() += v;
          break;
        case Channel::kYposition:
          t.y() += v;
          break;
        case Channel::kZposition:
          t.z() += v;
          break;
        default:
          R = R * AxisRotation(joint.channels[k], v);
          break;
      }
    }
    if (joint.parent < 0) {
      (*p_WJ)[j] = t;
      (*R_WJ)[j] = R;
    } else {
      (*p_WJ)[j] = (*p_WJ)[joint.parent] + (*R_WJ)[joint.parent] * t;
      (*R_WJ)[j] = (*R_WJ)[joint.parent] * R;
    }
  }
}

}  // namespace

const std::vector<std::string>& MocapLinkNames() {
  static const std::vector<std::string> kNames = [] {
    std::vector<std::string> names;
    for (const LinkSpec& spec : LinkSpecs()) names.emplace_back(spec.name);
    return names;
  }();
  return kNames;
}

MocapClip ImportBvhText(const std::string& text, const std::string& source,
                        const MocapImportOptions& options) {
  // Options first: they do not depend on the file.
  const char up = ToLower(options.up_axis);
  if (up != 'y' && up != 'z') {
    throw InputError(source + ": up_axis must be 'y' or 'z', got " +
                     Quote(std::string_view(&options.up_axis, 1)));
  }
  if (!(std::isfinite(options.unit_scale_m) && options.unit_scale_m >= 0)) {
    throw InputError(source + ": unit_scale_m must be > 0 (or 0 to detect), got " +
                     std::to_string(options.unit_scale_m));
  }
  if (options.frame_step < 1) {
    throw InputError(source + ": frame_step must be >= 1, got " +
                     std::to_string(options.frame_step));
  }
  if (options.start_frame < -1) {
    throw InputError(source + ": start_frame must be >= 0 (or -1 for auto), got " +
                     std::to_string(options.start_frame));
  }
  if (options.frame_count == 0 || options.frame_count < -1) {
    throw InputError(source + ": frame_count must be >= 1 (or -1 for all), got " +
                     std::to_string(options.frame_count));
  }
  const std::vector<std::string>& link_names = MocapLinkNames();
  for (const auto& [name, radius] : options.radius_override_m) {
    if (std::find(link_names.begin(), link_names.end(), name) == link_names.end()) {
      std::string known;
      for (const std::string& n : link_names) {
        if (!known.empty()) known += ", ";
        known += n;
      }
      throw InputError(source + ": radius_override_m names unknown link '" + name +
                       "' (links: " + known + ")");
    }
  }

  const BvhData bvh = ParseBvh(text, source);
  const double scale = options.unit_scale_m > 0 ? options.unit_scale_m : DetectUnitScale(bvh);
  const std::vector<LinkBinding> bindings = BindLinks(bvh, scale, source);

  int64_t start = options.start_frame;
  if (start < 0) start = FrameZeroIsReferencePose(bvh) ? 1 : 0;
  if (start >= bvh.num_frames) {
    throw InputError(source + ": start_frame " + std::to_string(start) +
                     " is past the last frame (the clip has " + std::to_string(bvh.num_frames) +
                     " frames)");
  }
  int64_t end = bvh.num_frames;
  if (options.frame_count > 0) end = std::min(end, start + options.frame_count);

  MocapClip clip;
  clip.unit_scale_m = scale;
  clip.frame_time_s = bvh.frame_time_s * options.frame_step;
  if (clip.frame_time_s * 1e6 < 1.0) {
    throw InputError(source + ": the time between kept frames (" +
                     std::to_string(clip.frame_time_s) +
                     " s) is below one microsecond; utime could not increase");
  }

  const std::vector<LinkSpec>& specs = LinkSpecs();
  std::vector<Link> links(specs.size());
  for (size_t i = 0; i < specs.size(); ++i) {
    links[i].name = specs[i].name;
    links[i].parent = specs[i].parent;
    links[i].a_L = Eigen::Vector3d::Zero();
    links[i].b_L = bindings[i].b_L;
    const auto it = options.radius_override_m.find(specs[i].name);
    links[i].radius = it != options.radius_override_m.end() ? it->second : specs[i].radius_m;
    clip.source_joints.push_back(bvh.joints[bindings[i].joint].name);
  }
  // The skeleton is named after the file: "walk" for walk.bvh and walk.bvh.gz.
  std::filesystem::path file = std::filesystem::path(source).filename();
  if (file.extension() == ".gz") file = file.stem();
  std::string name = file.stem().string();
  if (name.empty()) name = "bvh_clip";
  clip.skeleton = Skeleton::FromLinks(name, std::move(links), source);

  // Y-up -> Z-up: (x, y, z) -> (x, -z, y), a proper rotation.
  Eigen::Matrix3d C_WF = Eigen::Matrix3d::Identity();
  if (up == 'z') C_WF << 1, 0, 0, 0, 0, -1, 0, 1, 0;

  std::vector<Eigen::Matrix3d> R_FJ;
  std::vector<Eigen::Vector3d> p_FJ;
  clip.poses.reserve(
      static_cast<size_t>((end - start + options.frame_step - 1) / options.frame_step));
  int64_t kept = 0;
  for (int64_t frame = start; frame < end; frame += options.frame_step, ++kept) {
    ForwardKinematics(bvh, frame, &R_FJ, &p_FJ);
    Pose pose;
    pose.utime =
        std::llround(static_cast<double>(kept * options.frame_step) * bvh.frame_time_s * 1e6);
    pose.links.resize(specs.size());
    for (size_t i = 0; i < specs.size(); ++i) {
      const int j = bindings[i].joint;
      LinkPose& lp = pose.links[i];
      lp.p = C_WF * (scale * p_FJ[j]);
      lp.q = Eigen::Quaterniond(C_WF * R_FJ[j]);
      lp.q.normalize();
      if (!clip.poses.empty() && clip.poses.back().links[i].q.dot(lp.q) < 0) {
        lp.q.coeffs() *= -1.0;
      }
      if (!lp.p.allFinite() || !lp.q.coeffs().allFinite()) {
        throw InputError(source + ": frame " + std::to_string(frame) + ": link '" + specs[i].name +
                         "' gets a non-finite pose (values too large?)");
      }
    }
    clip.poses.push_back(std::move(pose));
  }
  return clip;
}

MocapClip ImportBvhFile(const std::string& path, const MocapImportOptions& options) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError(path + ": is a directory, not a BVH file");
  }
  // gzip-compressed files (by magic bytes) are inflated as meshes are.
  return ImportBvhText(ReadFileMaybeGzip(path), path, options);
}

void TranslateClip(MocapClip* clip, const Eigen::Vector3d& offset_W) {
  SWEPTCCD_CHECK(clip != nullptr);
  for (Pose& pose : clip->poses) {
    for (LinkPose& link : pose.links) link.p += offset_W;
  }
}

}  // namespace sweptccd
