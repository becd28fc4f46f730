// `sweptccd render`, run as the real binary on the bundled walk (CMU 02_01,
// imported as tools/demo.sh does) through the bundled apartment (MORSE):
// the contact picture and the timeline are PNG files that decode (libpng),
// have the requested size and real content, the witness marker sits at the
// pixel the JSON sidecar names, the first-contact marks of the timeline sit
// where the sidecar says; and bad input is refused with one line and exit 2.
// Runs on Mesa's llvmpipe through EGL in CI (never skipped: no context, no
// picture, the test fails).

#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/tools/run_binary.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kBinary = SWEPTCCD_BINARY;
const std::string kSource = SWEPTCCD_SOURCE_DIR;

using testing::ReadFile;
using testing::RunResult;

// A decoded PNG, 8-bit RGBA, top row first (libpng's simplified API).
struct Png {
  bool ok = false;
  std::string error;
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;
  std::array<int, 3> At(int x, int y) const {
    const uint8_t* p = &rgba[(static_cast<size_t>(y) * width + x) * 4];
    return {p[0], p[1], p[2]};
  }
  size_t DistinctColours() const {
    std::set<uint32_t> seen;
    for (size_t i = 0; i < rgba.size(); i += 4) {
      seen.insert(rgba[i] << 16 | rgba[i + 1] << 8 | rgba[i + 2]);
    }
    return seen.size();
  }
  size_t Count(std::array<int, 3> c) const {
    size_t n = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) n += At(x, y) == c;
    }
    return n;
  }
};

Png ReadPng(const std::string& path) {
  Png png;
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    png.error = image.message;
    return png;
  }
  image.format = PNG_FORMAT_RGBA;
  png.width = static_cast<int>(image.width);
  png.height = static_cast<int>(image.height);
  png.rgba.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, png.rgba.data(), 0, nullptr)) {
    png.error = image.message;
    png_image_free(&image);
    return png;
  }
  png.ok = true;
  return png;
}

std::array<int, 3> Rgb(const json& c) {
  return {c[0].get<int>(), c[1].get<int>(), c[2].get<int>()};
}

class RenderCommandTest : public ::testing::Test {
 protected:
  // The walk is imported once for all tests.
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("sweptccd_render_test_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    if (!::testing::UnitTest::GetInstance()->Failed()) fs::remove_all(*dir_, ec);
    delete dir_;
  }

  static std::string Path(const std::string& name) { return (*dir_ / name).string(); }

  RunResult Run(const std::vector<std::string>& args, double limit_s = 300) {
    static int run_count = 0;
    const int n = run_count++;
    return testing::RunBinary(kBinary, args, Path("run" + std::to_string(n) + ".out"),
                              Path("run" + std::to_string(n) + ".err"), limit_s);
  }

  // The bundled walk, imported as tools/demo.sh does (once).
  void ImportWalk() {
    skeleton_ = Path("walk_skeleton.json");
    poses_ = Path("walk_poses.jsonl");
    if (fs::exists(poses_)) return;
    const RunResult r = Run({"import-bvh", "--bvh", kSource + "/data/mocap/cmu_02_01_walk.bvh.gz",
                             "--up", "z", "--rate", "30", "--offset", "0", "-1", "0",
                             "--skeleton-out", skeleton_, "--poses-out", poses_});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  }

  std::vector<std::string> RenderArgs(std::initializer_list<std::string> extra) const {
    std::vector<std::string> args{"render", "--skeleton", skeleton_, "--poses",
                                  poses_,   "--env",      apartment_};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }

  // Runs a refusal: exit 2, exactly one line on stderr containing `needle`,
  // no picture written.
  void ExpectRefused(const std::vector<std::string>& args, const std::string& needle,
                     const std::string& picture) {
    SCOPED_TRACE(needle);
    const RunResult r = Run(args);
    EXPECT_TRUE(r.exited && r.code == 2) << r.Describe();
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("error: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(picture)) << picture;
  }

  static fs::path* dir_;
  std::string skeleton_, poses_;
  const std::string apartment_ = kSource + "/data/env/morse_apartment.ply.gz";
};

fs::path* RenderCommandTest::dir_ = nullptr;

TEST_F(RenderCommandTest, FirstContactPictureAndTimelineOfTheWalk) {
  ImportWalk();
  const std::string picture = Path("contact.png"), timeline = Path("timeline.png");
  const std::string sidecar = Path("contact.json");
  const RunResult r =
      Run(RenderArgs({"--out", picture, "--timeline", timeline, "--info-out", sidecar}));
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const json info = json::parse(ReadFile(sidecar));
  ASSERT_TRUE(info.contains("picture") && info.contains("timeline")) << info.dump(2);

  // The picture: the first pair with contact, as `query` would pick it.
  const json& pic = info["picture"];
  EXPECT_EQ(pic["result"], "contact");
  const int pair = pic["pair"].get<int>();
  EXPECT_GE(pair, 0);
  EXPECT_LE(pic["s_lo"].get<double>(), pic["s_hi"].get<double>());
  EXPECT_FALSE(pic["link_name"].get<std::string>().empty());
  EXPECT_EQ(pic["link_name"], info["links"][pic["link"].get<int>()]);
  EXPECT_EQ(pic["witness"]["point_env"].size(), 3u);
  const Png png = ReadPng(picture);
  ASSERT_TRUE(png.ok) << picture << ": " << png.error;
  EXPECT_EQ(png.width, 1280);
  EXPECT_EQ(png.height, 720);
  EXPECT_GT(png.DistinctColours(), 200u) << "the picture looks blank";
  const std::array<int, 3> background = png.At(png.width - 1, png.height - 1);
  EXPECT_LT(png.Count(background), static_cast<size_t>(png.width) * png.height * 9 / 10);
  // The witness marker, drawn without depth test in pure magenta, at the
  // pixel the sidecar names (and its 3x3 neighbourhood).
  ASSERT_TRUE(pic["marker"]["drawn"].get<bool>()) << pic.dump(2);
  const std::array<int, 3> magenta = Rgb(pic["marker"]["colour"]);
  EXPECT_EQ(magenta, (std::array<int, 3>{255, 0, 255}));
  const int mx = pic["marker"]["pixel"][0], my = pic["marker"]["pixel"][1];
  ASSERT_TRUE(mx >= 1 && my >= 1 && mx + 1 < png.width && my + 1 < png.height);
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      EXPECT_EQ(png.At(mx + dx, my + dy), magenta) << "at " << mx + dx << "," << my + dy;
    }
  }
  // The normal arrow is drawn in its own pure colour.
  EXPECT_GT(png.Count(Rgb(pic["normal_colour"])), 20u);

  // The timeline: size, content, a first-contact mark for every pair with
  // contact, the picture's pair among them.
  const json& tl = info["timeline"];
  const Png line = ReadPng(timeline);
  ASSERT_TRUE(line.ok) << timeline << ": " << line.error;
  EXPECT_EQ(line.width, 1280);
  EXPECT_EQ(line.height, 720);
  EXPECT_GT(line.DistinctColours(), 16u);
  EXPECT_LT(line.Count({255, 255, 255}), static_cast<size_t>(line.width) * line.height * 95 / 100);
  ASSERT_FALSE(tl["contact_marks"].empty()) << tl.dump(2);
  EXPECT_EQ(tl["contact_marks"][0]["pair"], pair);
  const std::array<int, 3> red = Rgb(tl["mark_colour"]);
  for (const json& mark : tl["contact_marks"]) {
    const int x = mark["pixel"][0], y = mark["pixel"][1];
    EXPECT_EQ(line.At(x, y), red) << mark.dump();
    // Inside the plot.
    EXPECT_GE(x, tl["plot"][0].get<int>());
    EXPECT_LE(x, tl["plot"][2].get<int>());
  }
  EXPECT_GT(line.Count(Rgb(tl["band_colour"])), 100u) << "no contact bands";
}

TEST_F(RenderCommandTest, ChosenPairSizeAndCamera) {
  ImportWalk();
  // A pair late in the walk (it walks into furniture), a smaller picture, and
  // a camera given by hand looking at the witness of the automatic one.
  const std::string first = Path("late.png"), first_info = Path("late.json");
  RunResult r = Run(RenderArgs({"--pair", "75", "--width", "640", "--height", "400", "--out", first,
                                "--info-out", first_info}));
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  json info = json::parse(ReadFile(first_info))["picture"];
  EXPECT_EQ(info["pair"], 75);
  Png png = ReadPng(first);
  ASSERT_TRUE(png.ok) << png.error;
  EXPECT_EQ(png.width, 640);
  EXPECT_EQ(png.height, 400);
  EXPECT_GT(png.DistinctColours(), 100u);
  // The walk is in the furniture from about 2.3 s (pair 69) on.
  ASSERT_EQ(info["result"], "contact") << info.dump(2);
  {
    ASSERT_TRUE(info["marker"]["drawn"].get<bool>());
    EXPECT_EQ(png.At(info["marker"]["pixel"][0], info["marker"]["pixel"][1]),
              (std::array<int, 3>{255, 0, 255}));
    const json& w = info["witness"]["point_env"];
    const std::string own = Path("own.png"), own_info = Path("own.json");
    const auto num = [](const json& v) { return std::to_string(v.get<double>()); };
    r = Run(RenderArgs({"--pair",
                        "75",
                        "--width",
                        "320",
                        "--height",
                        "240",
                        "--eye",
                        num(w[0]),
                        num(w[1].get<double>() - 2.5),
                        num(w[2].get<double>() + 1.0),
                        "--target",
                        num(w[0]),
                        num(w[1]),
                        num(w[2]),
                        "--fov",
                        "60",
                        "--up",
                        "z",
                        "--out",
                        own,
                        "--info-out",
                        own_info}));
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    const json own_json = json::parse(ReadFile(own_info))["picture"];
    png = ReadPng(own);
    ASSERT_TRUE(png.ok) << png.error;
    EXPECT_EQ(png.width, 320);
    EXPECT_EQ(png.height, 240);
    // Looking straight at the witness: the marker is at the centre.
    ASSERT_TRUE(own_json["marker"]["drawn"].get<bool>());
    const int x = own_json["marker"]["pixel"][0], y = own_json["marker"]["pixel"][1];
    EXPECT_NEAR(x, 160, 1);
    EXPECT_NEAR(y, 120, 1);
    EXPECT_EQ(png.At(x, y), (std::array<int, 3>{255, 0, 255}));
  }
}

TEST_F(RenderCommandTest, BadInputIsRefusedWithOneLine) {
  ImportWalk();
  const std::string png = Path("refused.png");
  ExpectRefused({"render", "--skeleton", Path("missing.json"), "--poses", poses_, "--env",
                 apartment_, "--out", png},
                "missing.json", png);
  ExpectRefused({"render", "--skeleton", skeleton_, "--poses", Path("missing.jsonl"), "--env",
                 apartment_, "--out", png},
                "missing.jsonl", png);
  ExpectRefused(RenderArgs({"--env", Path("missing.ply"), "--out", png}), "missing.ply", png);
  ExpectRefused(RenderArgs({"--pair", "100000", "--out", png}), "out of range", png);
  ExpectRefused(RenderArgs({"--width", "0", "--out", png}), "--width 0", png);
  ExpectRefused(RenderArgs({"--height", "100000", "--out", png}), "--height 100000", png);
  ExpectRefused(RenderArgs({"--fov", "0", "--out", png}), "--fov", png);
  ExpectRefused(RenderArgs({"--out", Path("no_such_folder/x.png")}), "no_such_folder", png);
  ExpectRefused(RenderArgs({"--out", Path("")}), "is a folder", png);
  ExpectRefused(RenderArgs({"--timeline", "/proc/sweptccd_timeline.png"}),
                "/proc/sweptccd_timeline.png", png);
  ExpectRefused(RenderArgs({}), "--out", png);
  ExpectRefused(RenderArgs({"--up", "w", "--out", png}), "--up", png);
  // Found by a day-one test: -1 drew the default pair; one path for two
  // pictures kept only the second; --out onto the pose stream destroyed it.
  ExpectRefused(RenderArgs({"--pair", "-1", "--out", png}), "--pair", png);
  ExpectRefused(RenderArgs({"--out", png, "--timeline", png}), "both name", png);
  {
    const std::string before = ReadFile(poses_);
    ExpectRefused(RenderArgs({"--out", poses_}), "--poses", png);
    EXPECT_EQ(ReadFile(poses_), before) << "the pose stream was touched";
  }
  // A stream that never comes near the apartment: no contact to draw.
  std::ifstream in(poses_);
  std::ofstream far(Path("far.jsonl"));
  std::string line;
  for (int i = 0; i < 4 && std::getline(in, line); ++i) {
    json pose = json::parse(line);
    for (json& link : pose["links"]) link[2] = link[2].get<double>() + 100.0;
    far << pose.dump() << '\n';
  }
  far.close();
  ExpectRefused({"render", "--skeleton", skeleton_, "--poses", Path("far.jsonl"), "--env",
                 apartment_, "--out", png},
                "no contact in the stream", png);
}

// `render --world`: an avatar and another entity (an avatar, a tracked
// object) at their first contact. Each entity has its own exact colour, so
// the test finds both in the picture (and the witness markers); not a
// screenshot comparison.
TEST_F(RenderCommandTest, WorldPairOfEntitiesAtFirstContact) {
  auto write = [](const std::string& name, const std::string& text) {
    std::ofstream(Path(name), std::ios::binary) << text;
    return Path(name);
  };
  auto line = [](int64_t utime, double y) {
    return "{\"utime\": " + std::to_string(utime) + ", \"links\": [[0, " + std::to_string(y) +
           ", 0, 1, 0, 0, 0]]}\n";
  };
  write("bar.json", R"({"name": "bar", "links": [{"name": "bar", "parent": null,
                        "a": [-0.5, 0, 0], "b": [0.5, 0, 0], "radius": 0.1}]})");
  // alice stays at the origin; bob comes down from y = 1 to 0 over 20 ms and
  // touches her at y = 0.2 (t = 1'016'000, alice's pair 1, tau 6000 us).
  write("alice.jsonl", line(1'000'000, 0) + line(1'010'000, 0) + line(1'020'000, 0));
  write("bob.jsonl", line(1'000'000, 1.0) + line(1'020'000, 0.0));
  // A plate falls through alice from y = 1 to -1: it touches at y = 0.1
  // (t = 1'009'000, alice's pair 0).
  write("plate.obj", "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 2 3\n");
  write("plate.jsonl",
        "{\"utime\": 1000000, \"pose\": [0, 1, 0, 1, 0, 0, 0]}\n"
        "{\"utime\": 1020000, \"pose\": [0, -1, 0, 1, 0, 0, 0]}\n");
  const std::string world = write("world.json", R"({"avatars": [
      {"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl"},
      {"id": "bob", "skeleton": "bar.json", "poses": "bob.jsonl", "motion": "independent"}],
    "objects": [{"id": "plate", "mesh": "plate.obj", "poses": "plate.jsonl"}], "env": []})");

  struct Case {
    std::string entity;
    int64_t pair;
    double tau_us;
  };
  for (const Case& c : {Case{"bob", 1, 6000}, Case{"plate", 0, 9000}}) {
    SCOPED_TRACE(c.entity);
    const std::string png = Path("entity_" + c.entity + ".png");
    const std::string sidecar = Path("entity_" + c.entity + ".json");
    const RunResult r =
        Run({"render", "--world", world, "--avatar", "alice", "--entity", c.entity, "--out", png,
             "--width", "320", "--height", "240", "--info-out", sidecar});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    const Png picture = ReadPng(png);
    ASSERT_TRUE(picture.ok) << picture.error;
    EXPECT_EQ(picture.width, 320);
    EXPECT_EQ(picture.height, 240);
    const json info = json::parse(ReadFile(sidecar));
    EXPECT_EQ(info["pair"].get<int64_t>(), c.pair);
    EXPECT_NEAR(info["tau_us"].get<double>(), c.tau_us, 100);  // eps = 1e-4 s.
    const auto avatar = Rgb(info["colours"]["avatar"]), other = Rgb(info["colours"]["entity"]);
    const auto witness = Rgb(info["colours"]["witness"]);
    EXPECT_NE(avatar, other);
    // Both entities are in the picture, each in its own colour, and both
    // witness markers were drawn.
    EXPECT_GT(picture.Count(avatar), 200u) << "avatar pixels";
    EXPECT_GT(picture.Count(other), 200u) << "entity pixels";
    ASSERT_EQ(info["witness"].size(), 2u);
    for (const json& m : info["witness"]) {
      ASSERT_TRUE(m["drawn"].get<bool>()) << m.dump();
      const int x = m["pixel"][0], y = m["pixel"][1];
      ASSERT_TRUE(x >= 0 && y >= 0 && x < 320 && y < 240) << m.dump();
      EXPECT_EQ(picture.At(x, y), witness) << m.dump();
    }
  }

  // --eye and --target place the camera as for the contact picture.
  const std::string placed = Path("entity_placed.png"), placed_info = Path("entity_placed.json");
  std::vector<std::string> args = {"render", "--world",    world,      "--avatar",
                                   "alice",  "--entity",   "bob",      "--out",
                                   placed,   "--info-out", placed_info};
  for (const char* extra :
       {"--width", "64", "--height", "48", "--eye", "0", "-3", "1", "--target", "0", "0.1", "0"}) {
    args.push_back(extra);
  }
  const RunResult r = Run(args);
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  const json placed_json = json::parse(ReadFile(placed_info));
  EXPECT_EQ(placed_json["camera"]["eye"], json::array({0.0, -3.0, 1.0}));
  EXPECT_EQ(placed_json["camera"]["target"], json::array({0.0, 0.1, 0.0}));
  EXPECT_EQ(ReadPng(placed).width, 64);

  // Bad choices are refused with one line.
  const std::string png = Path("entity_refused.png");
  ExpectRefused({"render", "--world", world, "--avatar", "carol", "--entity", "bob", "--out", png},
                "--avatar 'carol' is not one of its avatars (alice, bob)", png);
  ExpectRefused(
      {"render", "--world", world, "--avatar", "alice", "--entity", "alice", "--out", png},
      "--entity 'alice' is not another avatar or an object of it (bob, plate)", png);
  ExpectRefused({"render", "--world", world, "--avatar", "alice", "--entity", "bob", "--pair", "0",
                 "--out", png},
                "pair 0 of alice has no contact with bob", png);
  ExpectRefused({"render", "--world", world, "--avatar", "alice", "--entity", "bob", "--pair", "9",
                 "--out", png},
                "--pair 9 is out of range", png);
  ExpectRefused({"render", "--world", world, "--avatar", "alice", "--out", png},
                "--world needs --avatar ID and --entity ID", png);
  ExpectRefused({"render", "--world", world, "--avatar", "alice", "--entity", "bob", "--skeleton",
                 Path("bar.json"), "--out", png},
                "drop --skeleton, --poses and --env", png);
  ExpectRefused({"render", "--avatar", "alice", "--entity", "bob", "--out", png},
                "--avatar and --entity need --world", png);
  ExpectRefused({"render", "--out", png}, "give --skeleton and --poses", png);
}

}  // namespace
}  // namespace sweptccd
