#pragma once
// Shared by the libFuzzer targets of tests/fuzz: what a target may let escape
// and how file-based loaders receive the fuzzer's bytes.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace sweptccd::fuzz {

/// The fuzzer's bytes as a string (parsers take text).
inline std::string AsText(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// Writes the bytes to `path`. Aborts when the file cannot be written: a
/// harness failure is not a finding to hide.
inline void WriteFileOrAbort(const std::string& path, const void* data, size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr || (size > 0 && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();
  }
}

/// Writes the bytes to one file per process in /dev/shm (memory, not disk),
/// named with `extension` because loaders pick the format by it.
inline std::string WriteShmFile(const uint8_t* data, size_t size, const std::string& extension) {
  const std::string path =
      "/dev/shm/sweptccd-fuzz-" + std::to_string(getpid()) + "." + extension;
  WriteFileOrAbort(path, data, size);
  return path;
}

}  // namespace sweptccd::fuzz
