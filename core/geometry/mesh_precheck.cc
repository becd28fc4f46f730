#include "core/geometry/mesh_precheck.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <vector>

#include "core/errors.h"

namespace sweptccd {
namespace {

// Refuses the first line of data[begin, end) longer than max_line_bytes.
void CheckLineLengths(const std::string& data, size_t begin, size_t end, uint64_t max_line_bytes,
                      const std::string& path) {
  int64_t line = 1;
  for (size_t at = begin; at < end; ++line) {
    const void* nl = std::memchr(data.data() + at, '\n', end - at);
    const size_t stop = nl ? static_cast<size_t>(static_cast<const char*>(nl) - data.data()) : end;
    if (stop - at > max_line_bytes) {
      throw InputError(path + ": line " + std::to_string(line) + " is longer than the cap of " +
                       std::to_string(max_line_bytes) +
                       " bytes per line of a text mesh (corrupt, or not a text file; convert "
                       "it to binary PLY or STL)");
    }
    at = stop + 1;
  }
}

// --- PLY ------------------------------------------------------------------

struct PlyProperty {
  int size = 0;        // Scalar size, or list item size (bytes).
  int count_size = 0;  // > 0 for a list: the size of its length prefix.
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  size_t body = 0;     // Offset of the first byte after end_header's newline.
  std::string format;  // ascii, binary_little_endian or binary_big_endian.
  std::vector<PlyElement> elements;
};

// The offset just after the `end_header` line, searched within 1 MiB. assimp
// 5.2 loops forever on a header without end_header (assimp/assimp#5310).
size_t FindPlyBody(const std::string& data, const std::string& path) {
  constexpr size_t kMaxHeader = 1 << 20;
  for (size_t at = data.find("end_header"); at != std::string::npos && at < kMaxHeader;
       at = data.find("end_header", at + 1)) {
    if (at == 0 || data[at - 1] != '\n') continue;
    size_t after = at + 10;
    while (after < data.size() && data[after] == ' ') ++after;
    if (after < data.size() && data[after] == '\r') ++after;
    if (after < data.size() && data[after] == '\n') return after + 1;
    if (after == data.size()) return after;
  }
  throw InputError(path + ": the PLY header has no end_header line within its first 1 MiB "
                   "(truncated or corrupt)");
}

int PlyTypeSize(const std::string& t, const std::string& path) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" ||
      t == "float32") {
    return 4;
  }
  if (t == "double" || t == "float64") return 8;
  throw InputError(path + ": the PLY header names an unknown property type '" + t + "'");
}

// An element line "element NAME COUNT": COUNT must be decimal digits only and
// at most kMaxPlyElementCount.
PlyElement ParsePlyElement(std::istringstream& words, const std::string& line,
                           const std::string& path) {
  PlyElement e;
  std::string count;
  words >> e.name >> count;
  const bool digits = !count.empty() && count.size() <= 19 &&
                      count.find_first_not_of("0123456789") == std::string::npos;
  if (!digits) throw InputError(path + ": bad PLY element line '" + line + "'");
  e.count = std::strtoull(count.c_str(), nullptr, 10);
  if (e.count > kMaxPlyElementCount) {
    throw InputError(path + ": the PLY element '" + e.name + "' announces " + count +
                     " items, beyond the limit of " + std::to_string(kMaxPlyElementCount) +
                     " (corrupt header)");
  }
  return e;
}

// The header's lines, strictly: "ply", one "format", then "element NAME
// COUNT" lines each followed by its "property TYPE NAME" / "property list
// COUNT_TYPE ITEM_TYPE NAME" lines, with "comment" and "obj_info" lines
// anywhere, up to "end_header". Element names are unique, and so are property
// names within an element. Anything else is refused: assimp 5.2's PLY reader
// sizes its buffers from one declaration and fills them from another when a
// header repeats an element or a format line, and writes past the heap block
// (found by tools/fuzz.sh: tests/fuzz/corpus/fuzz_mesh_ply/
// repeated_vertex_element_heap_overflow).
PlyHeader ParsePlyHeader(const std::string& data, const std::string& path) {
  PlyHeader h;
  h.body = FindPlyBody(data, path);
  std::istringstream header(data.substr(0, h.body));
  std::string line;
  int number = 0;
  std::vector<std::vector<std::string>> property_names;
  auto refuse = [&](const std::string& why) {
    throw InputError(path + ": PLY header line " + std::to_string(number) + ": " + why);
  };
  while (std::getline(header, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string word; words >> word;) w.push_back(word);
    const std::string key = w.empty() ? "" : w[0];
    if (number == 1) {
      if (w.size() != 1 || key.size() != 3) refuse("the first line is not 'ply'");
      continue;
    }
    if (key == "comment" || key == "obj_info") continue;
    if (key == "end_header") break;
    if (key == "format") {
      if (!h.format.empty()) refuse("a second format line");
      if (!h.elements.empty()) refuse("the format line comes after an element");
      if (w.size() != 3) refuse("the format line is not 'format TYPE VERSION'");
      h.format = w[1];
      if (h.format != "ascii" && h.format != "binary_little_endian" &&
          h.format != "binary_big_endian") {
        throw InputError(path + ": the PLY header has no valid format line (got '" + h.format +
                         "')");
      }
    } else if (key == "element") {
      if (w.size() != 3) throw InputError(path + ": bad PLY element line '" + line + "'");
      std::istringstream rest(line.substr(line.find("element") + 7));
      h.elements.push_back(ParsePlyElement(rest, line, path));
      for (size_t e = 0; e + 1 < h.elements.size(); ++e) {
        if (h.elements[e].name == h.elements.back().name) {
          refuse("the element '" + h.elements.back().name + "' is declared twice");
        }
      }
      property_names.emplace_back();
    } else if (key == "property") {
      if (h.elements.empty()) throw InputError(path + ": PLY property before any element");
      PlyProperty prop;
      std::string name;
      if (w.size() >= 2 && w[1] == "list") {
        if (w.size() != 5) refuse("the list property is not 'property list COUNT_TYPE ITEM_TYPE NAME'");
        prop.count_size = PlyTypeSize(w[2], path);
        prop.size = PlyTypeSize(w[3], path);
        name = w[4];
      } else {
        if (w.size() != 3) refuse("the property line is not 'property TYPE NAME'");
        prop.size = PlyTypeSize(w[1], path);
        name = w[2];
      }
      for (const std::string& seen : property_names.back()) {
        if (seen == name) {
          refuse("the property '" + name + "' of element '" + h.elements.back().name +
                 "' is declared twice");
        }
      }
      property_names.back().push_back(name);
      h.elements.back().properties.push_back(prop);
    } else {
      refuse("'" + key.substr(0, 32) + "' is not a PLY header keyword (corrupt header)");
    }
  }
  if (h.format.empty()) {
    throw InputError(path + ": the PLY header has no valid format line (got '')");
  }
  return h;
}

// Refuses counts the body cannot hold, before anything walks or allocates for
// them. Binary: an element needs at least the sum of its scalar sizes and list
// length prefixes. ASCII: every property value is at least one character
// followed by one separator (the file's very last value may lack it).
void CheckPlyCounts(const PlyHeader& h, size_t body_bytes, const std::string& path) {
  const bool ascii = h.format == "ascii";
  const uint64_t available = body_bytes + (ascii ? 1 : 0);
  uint64_t needed = 0;  // Each term is below 2^52: the sum cannot wrap before it stops.
  for (const PlyElement& e : h.elements) {
    if (e.count > 0 && e.properties.empty()) {
      throw InputError(path + ": the PLY element '" + e.name + "' announces " +
                       std::to_string(e.count) + " items but has no properties (corrupt header)");
    }
    uint64_t min_size = 0;
    for (const PlyProperty& p : e.properties) {
      min_size += ascii ? 2 : static_cast<uint64_t>(p.count_size > 0 ? p.count_size : p.size);
    }
    needed += e.count * min_size;
    if (needed > available) {
      throw InputError(path + ": the PLY header announces more data than the file holds: element '" +
                       e.name + "' x " + std::to_string(e.count) + " needs at least " +
                       std::to_string(needed) + " bytes after the header, the file has " +
                       std::to_string(body_bytes) + " (truncated or corrupt)");
    }
  }
}

// Walks a binary body, reading list lengths, to find where it ends.
// (assimp zero-fills or misreads a truncated body: assimp/assimp#5341.)
void WalkBinaryPly(const std::string& data, const PlyHeader& h, const std::string& path) {
  const bool little = h.format == "binary_little_endian";
  const unsigned char* bytes = reinterpret_cast<const unsigned char*>(data.data());
  size_t pos = h.body;
  for (const PlyElement& e : h.elements) {
    for (uint64_t k = 0; k < e.count; ++k) {
      for (const PlyProperty& prop : e.properties) {
        uint64_t items = 1;
        if (prop.count_size > 0) {
          items = 0;
          if (pos + prop.count_size <= data.size()) {
            for (int b = 0; b < prop.count_size; ++b) {
              const int shift = 8 * (little ? b : prop.count_size - 1 - b);
              items |= static_cast<uint64_t>(bytes[pos + b]) << shift;
            }
            if (prop.count_size == 4 && (items >> 31)) {
              throw InputError(path + ": corrupt PLY list length in element '" + e.name + "' " +
                               std::to_string(k));
            }
          }
          pos += prop.count_size;
        }
        pos += items * prop.size;
        if (pos > data.size()) {
          throw InputError(path + ": the binary PLY data is truncated: it ends inside element '" +
                           e.name + "' " + std::to_string(k) + " of " + std::to_string(e.count));
        }
      }
    }
  }
}

// Walks an ASCII body token by token: one per scalar, a count and that many
// items per list.
void WalkAsciiPly(const std::string& data, const PlyHeader& h, const std::string& path) {
  size_t pos = h.body;
  auto next_token = [&](std::string* token) {
    while (pos < data.size() && std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
    const size_t start = pos;
    while (pos < data.size() && !std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
    if (token != nullptr) token->assign(data, start, pos - start);
    return pos > start;
  };
  std::string token;
  for (const PlyElement& e : h.elements) {
    for (uint64_t k = 0; k < e.count; ++k) {
      for (const PlyProperty& prop : e.properties) {
        uint64_t items = 1;
        if (prop.count_size > 0) {
          if (!next_token(&token)) {
            items = 1;  // Nothing left: the item loop below reports the truncation.
          } else {
            char* stop = nullptr;
            const long long n = std::strtoll(token.c_str(), &stop, 10);
            if (stop == token.c_str() || *stop != '\0' || n < 0) {
              throw InputError(path + ": bad PLY list length '" + token + "' in element '" +
                               e.name + "' " + std::to_string(k));
            }
            items = static_cast<uint64_t>(n);
          }
        }
        for (uint64_t i = 0; i < items; ++i) {
          if (!next_token(nullptr)) {
            throw InputError(path + ": the ASCII PLY data is truncated: it ends inside element '" +
                             e.name + "' " + std::to_string(k) + " of " + std::to_string(e.count));
          }
        }
      }
    }
  }
}

void PrecheckPly(const std::string& data, const std::string& path, uint64_t max_line_bytes) {
  // A .ply is checked whatever it holds: assimp picks its PLY reader by the
  // name, skips leading blank lines and takes any case mix of "ply" as the
  // magic number, so anything short of the exact first line "ply" is refused
  // here (fuzz findings: "PLY" and "\nply" headers reached assimp unchecked,
  // and it hung on one and read past a buffer on the other).
  const size_t eol = std::min(data.find('\n'), data.size());
  std::string first = data.substr(0, std::min<size_t>(eol, 8));
  if (!first.empty() && first.back() == '\r') first.pop_back();
  for (char& c : first) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (first != "ply") {
    throw InputError(path +
                     ": cannot parse the ply mesh: its first line is not 'ply' (not a PLY file)");
  }
  const PlyHeader h = ParsePlyHeader(data, path);
  const bool ascii = h.format == "ascii";
  CheckLineLengths(data, 0, ascii ? data.size() : h.body, max_line_bytes, path);
  CheckPlyCounts(h, data.size() - h.body, path);
  if (ascii) {
    WalkAsciiPly(data, h, path);
  } else {
    WalkBinaryPly(data, h, path);
  }
}

// --- STL ------------------------------------------------------------------

// assimp reads an STL as binary when its size is exactly 84 + 50 x count, else
// as text when it starts with "solid"; anything else is refused here with the
// sizes, so the message says what is wrong.
void PrecheckStl(const std::string& data, const std::string& path, uint64_t max_line_bytes) {
  if (data.size() >= 84) {
    uint32_t count = 0;
    for (int b = 0; b < 4; ++b) count |= static_cast<uint32_t>(static_cast<unsigned char>(data[80 + b])) << (8 * b);
    const uint64_t expected = 84 + 50 * uint64_t{count};
    if (expected == data.size()) return;
    const size_t first = data.find_first_not_of(" \t\r\n");
    if (first != std::string::npos && data.compare(first, 5, "solid") == 0) {
      CheckLineLengths(data, 0, data.size(), max_line_bytes, path);
      return;
    }
    throw InputError(path + ": cannot parse the stl mesh: its binary header announces " +
                     std::to_string(count) + " triangles, which need 84 + 50 x " +
                     std::to_string(count) + " = " + std::to_string(expected) +
                     " bytes, but the file size is " + std::to_string(data.size()) +
                     " bytes (truncated or corrupt), and it is not a text STL (no 'solid')");
  }
  const size_t first = data.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || data.compare(first, 5, "solid") != 0) {
    throw InputError(path + ": cannot parse the stl mesh: " + std::to_string(data.size()) +
                     " bytes is below the 84 of a binary STL header (truncated), and it is not "
                     "a text STL (no 'solid')");
  }
  CheckLineLengths(data, 0, data.size(), max_line_bytes, path);
}

}  // namespace

void PrecheckMeshData(const std::string& data, const std::string& format, const std::string& path,
                      uint64_t max_line_bytes) {
  if (format == "ply") {
    PrecheckPly(data, path, max_line_bytes);
  } else if (format == "stl") {
    PrecheckStl(data, path, max_line_bytes);
  } else {
    CheckLineLengths(data, 0, data.size(), max_line_bytes, path);
  }
}

}  // namespace sweptccd
