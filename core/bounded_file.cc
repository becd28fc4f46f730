#include "core/bounded_file.h"

#include <cctype>
#include <exception>
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

bool ReadBoundedLine(std::istream& in, uint64_t max_bytes, std::string* line, bool* too_long,
                     bool* blank) {
  line->clear();
  *too_long = false;
  *blank = true;
  std::streambuf* buf = in.rdbuf();
  bool any = false;
  for (;;) {
    int c;
    try {
      c = buf->sbumpc();
    } catch (const std::exception&) {
      // A read error (e.g. EISDIR: a folder opens, but cannot be read):
      // libstdc++'s filebuf throws where istream's own reads would set
      // badbit. Set it as they would; the reader stops and says bad().
      in.setstate(std::ios::badbit);
      return false;
    }
    if (c == std::char_traits<char>::eof()) {
      in.setstate(any ? std::ios::eofbit : std::ios::eofbit | std::ios::failbit);
      return any;
    }
    any = true;
    if (c == '\n') return true;
    if (*blank && !std::isspace(c)) *blank = false;
    if (line->size() < max_bytes) {
      line->push_back(static_cast<char>(c));
    } else {
      *too_long = true;
    }
  }
}

}  // namespace sweptccd
