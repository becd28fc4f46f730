#pragma once
// An 8-bit RGBA picture in memory, a few CPU drawing primitives (rectangles,
// lines, a tiny 5x7 bitmap font) and PNG output through libpng. Used by the
// scene renderer (text over the GL picture) and by the timeline of
// `sweptccd render`. No GL here.

#include <cstdint>
#include <string>
#include <vector>

namespace sweptccd::gpu {

struct Rgba {
  uint8_t r = 0, g = 0, b = 0, a = 255;
};

/// Row-major pixels, top row first, 4 bytes (R, G, B, A) per pixel.
struct RgbaImage {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;

  RgbaImage() = default;
  RgbaImage(int w, int h, Rgba fill);
  bool Inside(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
  Rgba Get(int x, int y) const;
  /// Blends `c` over the pixel with c.a as opacity (255: replaces exactly).
  /// Outside the picture: ignored.
  void Blend(int x, int y, Rgba c);
};

/// Fills [x0, x1) x [y0, y1) (clipped), blending with c.a.
void FillRect(RgbaImage* image, int x0, int y0, int x1, int y1, Rgba c);
/// A line from (x0, y0) to (x1, y1), `thickness` pixels wide (square pen).
void DrawLine(RgbaImage* image, double x0, double y0, double x1, double y1, Rgba c,
              int thickness = 1);
/// Text in the built-in 5x7 font (letters are drawn lower-case; unknown
/// characters as a box), top-left corner at (x, y), each font pixel
/// `scale` x `scale` pixels, 6 * scale pixels per character.
void DrawText(RgbaImage* image, int x, int y, const std::string& text, Rgba c, int scale = 1);
int TextWidth(const std::string& text, int scale = 1);
inline int TextHeight(int scale = 1) { return 7 * scale; }

/// Writes `image` as an 8-bit RGB PNG (alpha dropped). Throws InputError
/// naming the path when the file cannot be written.
void WritePngFile(const std::string& path, const RgbaImage& image);

}  // namespace sweptccd::gpu
