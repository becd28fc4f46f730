#pragma once
// Reading a whole file from outside with a cap on its size.

#include <cstdint>
#include <fstream>
#include <istream>
#include <string>

namespace sweptccd {

/// Cap on a skeleton or collision filter JSON file: 16 MiB (a 256-link
/// skeleton is about 40 KiB).
inline constexpr uint64_t kMaxJsonFileBytes = uint64_t{16} << 20;

/// Opens the file at `path` for reading (binary). Throws InputError("PATH:
/// cannot open the WHAT") when it cannot be opened, and ("PATH: is a folder,
/// where the WHAT should be") for a folder, which opens but fails every
/// read: so a command refuses it at once, before loading anything else.
/// `what` names the file's role ("pose stream file").
std::ifstream OpenInputFile(const std::string& path, const std::string& what);

/// Reads the whole file at `path`, holding at most `max_bytes` of it: a longer
/// file is refused after reading max_bytes + 1 bytes. `what` names the file's
/// role in messages ("skeleton file"); `fix` ends the over-cap message (how to
/// raise the cap, or what the file should be). Throws InputError("PATH:
/// problem") when the file cannot be opened or read or is over the cap.
/// Thread-safe.
std::string ReadFileBounded(const std::string& path, uint64_t max_bytes, const std::string& what,
                            const std::string& fix);

/// Reads one line (to '\n' or the end of the stream) through the stream
/// buffer, keeping at most `max_bytes` of it in *line (without the newline):
/// a longer line is read to its end without being kept, and *too_long says
/// so. *blank: the line held only whitespace. Returns false at the end of
/// the stream with nothing read; a read error sets badbit and returns false.
/// The one line rule of the pose and object pose readers.
bool ReadBoundedLine(std::istream& in, uint64_t max_bytes, std::string* line, bool* too_long,
                     bool* blank);

}  // namespace sweptccd
