#include "tools/output_paths.h"

#include <filesystem>
#include <system_error>

#include "core/errors.h"

namespace sweptccd {

namespace {

namespace fs = std::filesystem;

// The same file: equal lexically normalised absolute paths, or (both
// existing) the same inode, which also catches links and "./a" vs "a".
bool SameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::equivalent(a, b, ec) && !ec) return true;
  const fs::path pa = fs::absolute(a, ec).lexically_normal();
  if (ec) return a == b;
  const fs::path pb = fs::absolute(b, ec).lexically_normal();
  if (ec) return a == b;
  return pa == pb;
}

bool IsFile(const std::string& path) { return !path.empty() && path != "-"; }

}  // namespace

void RefuseClashingPaths(const std::vector<NamedPath>& inputs,
                         const std::vector<NamedPath>& outputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [out_flag, out_path] = outputs[i];
    if (!IsFile(out_path)) continue;
    for (const auto& [in_flag, in_path] : inputs) {
      if (IsFile(in_path) && SameFile(out_path, in_path)) {
        throw InputError(out_flag + " " + out_path + " is also the " + in_flag +
                         " input; writing it would destroy the input: choose another file");
      }
    }
    for (size_t j = 0; j < i; ++j) {
      if (IsFile(outputs[j].second) && SameFile(out_path, outputs[j].second)) {
        throw InputError(outputs[j].first + " and " + out_flag + " both name " + out_path +
                         "; one would replace the other: give two files");
      }
    }
  }
}

}  // namespace sweptccd
