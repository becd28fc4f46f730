#include "core/bounded_file.h"

#include <filesystem>
#include <fstream>
#include <system_error>

#include "core/errors.h"

namespace sweptccd {

std::ifstream OpenInputFile(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the " + what);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError(path + ": is a folder, where the " + what + " should be");
  }
  return in;
}

std::string ReadFileBounded(const std::string& path, uint64_t max_bytes, const std::string& what,
                            const std::string& fix) {
  std::ifstream in = OpenInputFile(path, what);
  std::string text;
  char chunk[1 << 16];
  while (in) {
    in.read(chunk, sizeof(chunk));
    const uint64_t got = static_cast<uint64_t>(in.gcount());
    if (text.size() + got > max_bytes) {
      throw InputError(path + ": the " + what + " holds more than the cap of " +
                       std::to_string(max_bytes) + " bytes; " + fix);
    }
    text.append(chunk, got);
  }
  if (in.bad()) throw InputError(path + ": error while reading the " + what);
  return text;
}

}  // namespace sweptccd
