#include "core/json_text.h"

namespace sweptccd {

std::string NulByteProblem(const std::string& text) {
  const size_t at = text.find('\0');
  if (at == std::string::npos) return "";
  return "a NUL byte at offset " + std::to_string(at) + " (JSON text never holds one)";
}

}  // namespace sweptccd
