#include "render/raster_image.h"

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "core/errors.h"

namespace sweptccd::gpu {

namespace {

// 5x7 glyphs, one string of 35 characters per glyph ('#' set), rows top down.
struct Glyph {
  char c;
  const char* rows;
};
constexpr Glyph kFont[] = {
    {';', "......##...##.........##....#...#.."},  {'!', "..#....#....#....#....#.........#.."},
    {'0', ".###.#...##..###.#.###..##...#.###."},  {'1', "..#...##....#....#....#....#...###."},
    {'2', ".###.#...#....#...#...#...#...#####"},  {'3', "#####...#...#.....#.....##...#.###."},
    {'4', "...#...##..#.#.#..#.#####...#....#."},  {'5', "######....####.....#....##...#.###."},
    {'6', "..##..#...#....####.#...##...#.###."},  {'7', "#####....#...#...#...#....#....#..."},
    {'8', ".###.#...##...#.###.#...##...#.###."},  {'9', ".###.#...##...#.####....#...#..##.."},
    {'a', "...........###.....#.#####...#.####"},  {'b', "#....#....#.##.##..##...##...#####."},
    {'c', "...........###.#....#....#...#.###."},  {'d', "....#....#.##.##..###...##...#.####"},
    {'e', "...........###.#...#######.....###."},  {'f', "..##..#..#.#...###...#....#....#..."},
    {'g', "......#####...##...#.####....#.###."},  {'h', "#....#....#.##.##..##...##...##...#"},
    {'i', "..#........##....#....#....#...###."},  {'j', "...#........##....#....#.#..#..##.."},
    {'k', "#....#....#..#.#.#..##...#.#..#..#."},  {'l', ".##....#....#....#....#....#...###."},
    {'m', "..........##.#.#.#.##.#.##...##...#"},  {'n', "..........#.##.##..##...##...##...#"},
    {'o', "...........###.#...##...##...#.###."},  {'p', "..........####.#...#####.#....#...."},
    {'q', "...........##.##..##.####....#....#"},  {'r', "..........#.##.##..##....#....#...."},
    {'s', "...........###.#.....###.....#####."},  {'t', ".#....#...###...#....#....#..#..##."},
    {'u', "..........#...##...##...##..##.##.#"},  {'v', "..........#...##...##...#.#.#...#.."},
    {'w', "..........#...##...##.#.##.#.#.#.#."},  {'x', "..........#...#.#.#...#...#.#.#...#"},
    {'y', "..........#...##...#.####....#.###."},  {'z', "..........#####...#...#...#...#####"},
    {'.', "..........................##...##.."},  {',', ".....................##....#...#..."},
    {'-', "...............#####..............."},  {'+', ".......#....#..#####..#....#......."},
    {'_', "..............................#####"},  {':', "......##...##........##...##......."},
    {'(', "...#...#...#....#....#.....#.....#."},  {')', ".#.....#.....#....#....#...#...#..."},
    {'[', ".###..#....#....#....#....#....###."},  {']', ".###....#....#....#....#....#..###."},
    {'/', "..............#...#...#...#...#...."},  {'=', "..........#####.....#####.........."},
    {'>', ".#.....#.....#.....#...#...#...#..."},  {'<', "...#...#...#...#.....#.....#.....#."},
    {'\'', "..#....#...#......................."},
};

const char* GlyphRows(char c) {
  static const char kBox[] = "######...##...##...##...##...######";
  const char lower = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const Glyph& g : kFont) {
    if (g.c == lower) return g.rows;
  }
  return kBox;
}

}  // namespace

RgbaImage::RgbaImage(int w, int h, Rgba fill) : width(w), height(h) {
  pixels.resize(static_cast<size_t>(w) * h * 4);
  for (size_t i = 0; i < pixels.size(); i += 4) {
    pixels[i] = fill.r;
    pixels[i + 1] = fill.g;
    pixels[i + 2] = fill.b;
    pixels[i + 3] = fill.a;
  }
}

Rgba RgbaImage::Get(int x, int y) const {
  const uint8_t* p = &pixels[(static_cast<size_t>(y) * width + x) * 4];
  return Rgba{p[0], p[1], p[2], p[3]};
}

void RgbaImage::Blend(int x, int y, Rgba c) {
  if (!Inside(x, y)) return;
  uint8_t* p = &pixels[(static_cast<size_t>(y) * width + x) * 4];
  if (c.a == 255) {
    p[0] = c.r, p[1] = c.g, p[2] = c.b, p[3] = 255;
    return;
  }
  const int a = c.a;
  auto mix = [a](uint8_t dst, uint8_t src) {
    return static_cast<uint8_t>((src * a + dst * (255 - a) + 127) / 255);
  };
  p[0] = mix(p[0], c.r);
  p[1] = mix(p[1], c.g);
  p[2] = mix(p[2], c.b);
  p[3] = 255;
}

void FillRect(RgbaImage* image, int x0, int y0, int x1, int y1, Rgba c) {
  x0 = std::max(x0, 0), y0 = std::max(y0, 0);
  x1 = std::min(x1, image->width), y1 = std::min(y1, image->height);
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) image->Blend(x, y, c);
  }
}

void DrawLine(RgbaImage* image, double x0, double y0, double x1, double y1, Rgba c, int thickness) {
  const double dx = x1 - x0, dy = y1 - y0;
  const int steps = std::max(1, static_cast<int>(std::ceil(std::max(std::abs(dx), std::abs(dy)))));
  if (steps > 100000) return;  // Absurd coordinates: nothing sensible to draw.
  const int lo = -(thickness - 1) / 2, hi = thickness / 2;
  int last_x = INT32_MIN, last_y = INT32_MIN;
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / steps;
    const int x = static_cast<int>(std::lround(x0 + t * dx));
    const int y = static_cast<int>(std::lround(y0 + t * dy));
    if (x == last_x && y == last_y) continue;
    last_x = x, last_y = y;
    if (c.a == 255) {
      FillRect(image, x + lo, y + lo, x + hi + 1, y + hi + 1, c);
    } else {
      image->Blend(x, y, c);  // Translucent lines stay one pixel (no double blending).
    }
  }
}

void DrawText(RgbaImage* image, int x, int y, const std::string& text, Rgba c, int scale) {
  int pen = x;
  for (char ch : text) {
    if (ch != ' ') {
      const char* rows = GlyphRows(ch);
      const size_t n = std::strlen(rows);
      for (int r = 0; r < 7; ++r) {
        for (int col = 0; col < 5; ++col) {
          const size_t k = static_cast<size_t>(r * 5 + col);
          if (k < n && rows[k] == '#') {
            FillRect(image, pen + col * scale, y + r * scale, pen + (col + 1) * scale,
                     y + (r + 1) * scale, c);
          }
        }
      }
    }
    pen += 6 * scale;
  }
}

int TextWidth(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * 6 * scale - scale;
}

namespace {

// libpng's default handlers print to stderr; the caller reports one line.
[[noreturn]] void PngError(png_structp png, png_const_charp) { png_longjmp(png, 1); }
void PngWarning(png_structp, png_const_charp) {}

}  // namespace

void WritePngFile(const std::string& path, const RgbaImage& image) {
  FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    throw InputError(path + ": cannot write the picture (" + std::strerror(errno) + ")");
  }
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, PngError, PngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  std::vector<uint8_t> row(static_cast<size_t>(image.width) * 3);
  bool ok = png != nullptr && info != nullptr;
  if (ok && setjmp(png_jmpbuf(png)) == 0) {
    png_init_io(png, file);
    png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < image.height; ++y) {
      const uint8_t* src = &image.pixels[static_cast<size_t>(y) * image.width * 4];
      for (int x = 0; x < image.width; ++x) {
        row[3 * x] = src[4 * x];
        row[3 * x + 1] = src[4 * x + 1];
        row[3 * x + 2] = src[4 * x + 2];
      }
      png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
  } else {
    ok = false;
  }
  png_destroy_write_struct(png ? &png : nullptr, info ? &info : nullptr);
  const bool closed = std::fclose(file) == 0;
  if (!ok || !closed) throw InputError(path + ": error while writing the PNG picture");
}

}  // namespace sweptccd::gpu
