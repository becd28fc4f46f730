#pragma once
// Sanity checks of a mesh file's bytes before any parser allocates for them.
//
// assimp trusts the counts a header announces (a PLY `element vertex
// 2000000000` with no properties kept it busy for 25 s; a binary STL count is
// used to size buffers) and hangs on some broken PLY headers. Every check here
// is linear in the file size and allocates nothing in proportion to a count,
// so a hostile header is refused in milliseconds, before assimp sees it.

#include <cstdint>
#include <string>

namespace sweptccd {

/// Largest element count a PLY header may announce (int32, as assimp indexes).
inline constexpr uint64_t kMaxPlyElementCount = 0x7fffffff;

/// Checks `data` (the whole, already decompressed, file) for the format named
/// by `format` ("obj", "ply" or "stl"):
/// - PLY: a header ending in end_header within 1 MiB whose lines are, strictly,
///   "ply", one valid format line before any element, element and property
///   lines of the right shape (known property types; element names unique,
///   property names unique within their element), comments; every element count <= kMaxPlyElementCount; no element
///   with a non-zero count and no properties; the counts must fit the bytes
///   after the header (binary: count x the element's minimum size, a list
///   counting its length prefix only; ASCII: two bytes per property value,
///   a value and its separator); then the body is walked to find truncation.
/// - STL: either a binary file of exactly 84 + 50 x count bytes, or a text
///   file starting with `solid`.
/// - Text formats (OBJ, ASCII STL, ASCII PLY): no line longer than
///   `max_line_bytes` bytes.
/// Throws InputError("PATH: problem") naming what is wrong; returns when the
/// file may be given to the parser. Thread-safe (no shared state).
void PrecheckMeshData(const std::string& data, const std::string& format, const std::string& path,
                      uint64_t max_line_bytes);

}  // namespace sweptccd
