// Fuzzes the world file of SPEC section 8 (LoadWorldFile) and the tracked
// object's pose line (ParseObjectPoseLine): the input is the world file,
// written beside small valid files it may name (bar.json, alice.jsonl,
// cup.obj, cup.jsonl, floor.obj), so inputs that parse go on to load their
// skeleton, poses and meshes and to check ids, motions and ignore rules. A
// world, or InputError; each input line is also an object pose line.

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

#include "core/errors.h"
#include "core/world/world_file.h"
#include "tests/fuzz/fuzz_input.h"

namespace {

void WriteOrAbort(const std::string& path, const std::string& text) {
  sweptccd::fuzz::WriteFileOrAbort(path, text.data(), text.size());
}

// The folder of the files a world may name, one per process in /dev/shm.
std::string MakeFolder() {
  const std::string dir = "/dev/shm/sweptccd-fuzz-world-" + std::to_string(getpid());
  if (mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) {
    std::perror(dir.c_str());
    std::abort();
  }
  WriteOrAbort(dir + "/bar.json",
               R"({"name": "bar", "links": [{"name": "bar", "parent": null, )"
               R"("a": [-0.5, 0, 0], "b": [0.5, 0, 0], "radius": 0.1}]})");
  WriteOrAbort(dir + "/alice.jsonl",
               "{\"utime\": 1000000, \"links\": [[0, 0, 0, 1, 0, 0, 0]]}\n"
               "garbage\n"
               "{\"utime\": 1010000, \"links\": [[0, 0.1, 0, 1, 0, 0, 0]]}\n");
  WriteOrAbort(dir + "/cup.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n");
  WriteOrAbort(dir + "/cup.jsonl",
               "{\"utime\": 1005000, \"pose\": [0, 0.5, 0, 1, 0, 0, 0]}\n"
               "{\"utime\": 1015000, \"pose\": [0, 0, 0, 0, 0, 1, 0]}\n");
  WriteOrAbort(dir + "/floor.obj", "v -9 -1 -9\nv 9 -1 -9\nv 9 -1 9\nv -9 -1 9\nf 1 2 3 4\n");
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string dir = MakeFolder();
  const std::string text = sweptccd::fuzz::AsText(data, size);
  WriteOrAbort(dir + "/world.json", text);
  try {
    const sweptccd::world::LoadedWorld w = sweptccd::world::LoadWorldFile(dir + "/world.json");
    (void)w;
  } catch (const sweptccd::InputError&) {
  }
  std::istringstream lines(text);
  std::string line;
  sweptccd::world::RigidSample sample;
  std::string error;
  while (std::getline(lines, line)) sweptccd::world::ParseObjectPoseLine(line, &sample, &error);
  return 0;
}
