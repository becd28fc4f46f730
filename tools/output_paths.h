#pragma once
// Checks the commands make before writing any output file: no output is one
// of the inputs (it would be truncated before being read), and no two outputs
// are the same file (the second would silently replace the first).

#include <string>
#include <utility>
#include <vector>

namespace sweptccd {

/// A file named on the command line: the flag and the path.
using NamedPath = std::pair<std::string, std::string>;

/// Throws InputError naming both flags when an output names the same file as
/// an input or as another output. Empty paths are skipped; "-" and standard
/// streams are not files and are skipped too.
void RefuseClashingPaths(const std::vector<NamedPath>& inputs,
                         const std::vector<NamedPath>& outputs);

}  // namespace sweptccd
