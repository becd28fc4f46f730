#include "render/timeline_picture.h"

#include <algorithm>
#include <cmath>

#include "core/errors.h"
#include "render/picture_style.h"

namespace sweptccd::gpu {

namespace {

using internal::ColourJson;
using internal::Fixed;
using nlohmann::json;

constexpr Rgba kPaper{255, 255, 255, 255};
constexpr Rgba kGrid{225, 225, 225, 255};
constexpr Rgba kBlack{0, 0, 0, 255};
constexpr Rgba kContactBand{255, 200, 200, 255};
constexpr Rgba kContactMark{255, 0, 0, 255};
constexpr int kMarkHalf = 4;  // First-contact marks: 9x9 squares at the top of the plot.
// One colour per link (cycled); none is pure red (the contact marks).
constexpr Rgba kLinkColours[] = {
    {31, 119, 180, 255},  {44, 160, 44, 255},   {148, 103, 189, 255}, {140, 86, 75, 255},
    {227, 119, 194, 255}, {110, 110, 110, 255}, {188, 189, 34, 255},  {23, 190, 207, 255},
    {255, 127, 14, 255},  {0, 0, 140, 255},     {0, 128, 128, 255},   {128, 0, 128, 255},
    {90, 150, 220, 255},  {100, 200, 90, 255},  {180, 140, 60, 255},  {60, 60, 60, 255}};

struct TimelineSample {
  double t_s;
  std::vector<double> separation;  // Per link, clamped to [0, max].
};

// The stream's time axis and the plot's pixel box.
struct Plot {
  int64_t utime_start = 0;
  double span_s = 0;
  int scale = 1, th = 0;  // Font scale and text height.
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  double max_sep = 0;
  double Seconds(double utime) const { return (utime - static_cast<double>(utime_start)) * 1e-6; }
  double X(double t_s) const { return x0 + t_s / span_s * (x1 - x0); }
  double Y(double sep) const { return y1 - std::clamp(sep, 0.0, max_sep) / max_sep * (y1 - y0); }
};

// Separations at s = 0 of every pair, at s = 1 of the last one, and at the
// first contact of pairs with contact.
std::vector<TimelineSample> Sample(const Plot& plot, const Skeleton& skeleton,
                                   const CcdEngine& engine, const std::vector<PairOutcome>& pairs,
                                   const std::vector<std::optional<QueryResult>>& results,
                                   MotionModel model) {
  const int n = skeleton.num_links();
  std::vector<TimelineSample> samples;
  auto sample = [&](const PairMotion& motion, double s, double utime) {
    TimelineSample ts{plot.Seconds(utime), std::vector<double>(n, plot.max_sep)};
    for (int link = 0; link < n; ++link) {
      ContactRecord record;
      if (engine.Separation(motion, LinkIndex(link), s, plot.max_sep, &record)) {
        ts.separation[link] = std::clamp(record.separation, 0.0, plot.max_sep);
      }
    }
    samples.push_back(std::move(ts));
  };
  size_t last_valid = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (pairs[k].valid) last_valid = k;
  }
  for (size_t k = 0; k < pairs.size(); ++k) {
    const PairOutcome& p = pairs[k];
    if (!p.valid) continue;
    const PairMotion motion(skeleton, p.pose0, p.pose1, model);
    const double duration = static_cast<double>(p.pose1.utime - p.pose0.utime);
    sample(motion, 0, static_cast<double>(p.pose0.utime));
    if (results[k]->contact && results[k]->s_lo > 0) {
      sample(motion, results[k]->s_lo, p.pose0.utime + results[k]->s_lo * duration);
    }
    if (k == last_valid) sample(motion, 1, static_cast<double>(p.pose1.utime));
  }
  return samples;
}

// The time axis from the valid pairs and the layout from the picture size.
Plot Layout(const TimelineOptions& o, const Skeleton& skeleton,
            const std::vector<PairOutcome>& pairs, const std::string& stream_name) {
  Plot plot;
  plot.max_sep = o.max_separation_m;
  int64_t utime_end = 0;
  bool any = false;
  for (const PairOutcome& p : pairs) {
    if (!p.valid) continue;
    if (!any) plot.utime_start = p.pose0.utime;
    utime_end = p.pose1.utime;
    any = true;
  }
  if (!any) throw InputError(stream_name + ": no valid pair in the stream for the timeline");
  plot.span_s = std::max(plot.Seconds(static_cast<double>(utime_end)), 1e-6);
  const int n = skeleton.num_links();
  plot.scale = o.width >= 1000 ? 2 : 1;
  plot.th = TextHeight(plot.scale);
  int legend_w = 0;
  for (int i = 0; i < n; ++i) {
    legend_w = std::max(legend_w, TextWidth(skeleton.link(i).name, plot.scale));
  }
  plot.x0 = 12 * plot.scale + TextWidth("0.50", plot.scale) + 8 * plot.scale;
  plot.x1 = o.width - (legend_w + plot.th + 24 * plot.scale);
  plot.y0 = 4 * plot.th + 16 * plot.scale;
  plot.y1 = o.height - (2 * plot.th + 20 * plot.scale);
  const int legend_rows_fit = (o.height - plot.y0) / (plot.th + 4 * plot.scale);
  if (plot.x1 - plot.x0 < 100 || plot.y1 - plot.y0 < 60 || legend_rows_fit < n) {
    throw InputError("sweptccd render: --width/--height " + std::to_string(o.width) + "x" +
                     std::to_string(o.height) + " is too small for the timeline (try 1280x720)");
  }
  return plot;
}

void DrawTitle(const Plot& p, RgbaImage* image) {
  DrawText(image, p.x0, 6 * p.scale,
           "separation from the environment per link (m, clamped at " + Fixed(p.max_sep, 2) +
               ") against time (s)",
           kBlack, p.scale);
  DrawText(image, p.x0, 6 * p.scale + p.th + 4 * p.scale,
           "red bands: pairs with contact; red marks: first contact (t_lo)", kContactMark, p.scale);
}

// Pairs with contact as bands under the grid.
void DrawContactBands(const Plot& p, const std::vector<PairOutcome>& pairs,
                      const std::vector<std::optional<QueryResult>>& results, RgbaImage* image) {
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!pairs[k].valid || !results[k]->contact) continue;
    const int bx0 =
        static_cast<int>(std::floor(p.X(p.Seconds(static_cast<double>(pairs[k].pose0.utime)))));
    const int bx1 =
        static_cast<int>(std::ceil(p.X(p.Seconds(static_cast<double>(pairs[k].pose1.utime)))));
    FillRect(image, bx0, p.y0, std::max(bx1, bx0 + 2), p.y1, kContactBand);
  }
}

// Grid, axes and their labels.
void DrawAxes(const Plot& p, RgbaImage* image) {
  const int scale = p.scale, th = p.th;
  const int y_ticks = 5;
  for (int i = 0; i <= y_ticks; ++i) {
    const double sep = p.max_sep * i / y_ticks;
    const int y = static_cast<int>(std::lround(p.Y(sep)));
    DrawLine(image, p.x0, y, p.x1, y, kGrid);
    const std::string label = Fixed(sep, 2);
    DrawText(image, p.x0 - 6 * scale - TextWidth(label, scale), y - th / 2, label, kBlack, scale);
  }
  const double steps[] = {0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 30, 60, 120, 300, 600, 1800, 3600};
  double step = steps[0];
  for (double s : steps) {
    step = s;
    if (p.span_s / s <= 12) break;
  }
  for (int i = 0; i * step <= p.span_s + 1e-9; ++i) {
    const int x = static_cast<int>(std::lround(p.X(i * step)));
    DrawLine(image, x, p.y0, x, p.y1, kGrid);
    DrawLine(image, x, p.y1, x, p.y1 + 4 * scale, kBlack);
    const std::string label = Fixed(i * step, step < 1 ? (step < 0.1 ? 2 : 1) : 0);
    DrawText(image, x - TextWidth(label, scale) / 2, p.y1 + 7 * scale, label, kBlack, scale);
  }
  DrawLine(image, p.x0, p.y0, p.x0, p.y1, kBlack);
  DrawLine(image, p.x0, p.y1, p.x1, p.y1, kBlack);
  DrawText(image, (p.x0 + p.x1) / 2 - TextWidth("time (s)", scale) / 2, p.y1 + th + 12 * scale,
           "time (s)", kBlack, scale);
  DrawText(image, 4 * scale, p.y0 - th - 8 * scale, "separation (m)", kBlack, scale);
}

// One line per link, and the legend.
void DrawLinks(const Plot& p, const Skeleton& skeleton, const std::vector<TimelineSample>& samples,
               RgbaImage* image) {
  const int n = skeleton.num_links();
  for (int link = 0; link < n; ++link) {
    const Rgba c = kLinkColours[link % std::size(kLinkColours)];
    for (size_t i = 1; i < samples.size(); ++i) {
      DrawLine(image, p.X(samples[i - 1].t_s), p.Y(samples[i - 1].separation[link]),
               p.X(samples[i].t_s), p.Y(samples[i].separation[link]), c, p.scale);
    }
  }
  for (int link = 0; link < n; ++link) {
    const int y = p.y0 + link * (p.th + 4 * p.scale);
    const Rgba c = kLinkColours[link % std::size(kLinkColours)];
    FillRect(image, p.x1 + 10 * p.scale, y, p.x1 + 10 * p.scale + p.th, y + p.th, c);
    DrawText(image, p.x1 + 12 * p.scale + p.th, y, skeleton.link(link).name, c, p.scale);
  }
}

// First-contact marks, drawn last so nothing covers them. Returns them.
json DrawContactMarks(const Plot& p, const std::vector<PairOutcome>& pairs,
                      const std::vector<std::optional<QueryResult>>& results, RgbaImage* image) {
  json marks = json::array();
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!pairs[k].valid || !results[k]->contact) continue;
    const PairOutcome& pair = pairs[k];
    const double t_lo = pair.pose0.utime +
                        results[k]->s_lo * static_cast<double>(pair.pose1.utime - pair.pose0.utime);
    const int x = std::clamp(static_cast<int>(std::lround(p.X(p.Seconds(t_lo)))), p.x0, p.x1);
    const int y = p.y0 + kMarkHalf + 2;
    DrawLine(image, x, p.y0, x, p.y1, kContactMark);
    FillRect(image, x - kMarkHalf, y - kMarkHalf, x + kMarkHalf + 1, y + kMarkHalf + 1,
             kContactMark);
    marks.push_back(
        {{"pair", pair.pair}, {"t_lo_s", p.Seconds(t_lo)}, {"pixel", json::array({x, y})}});
  }
  return marks;
}

}  // namespace

RgbaImage DrawTimeline(const TimelineOptions& o, const Skeleton& skeleton, const CcdEngine& engine,
                       const std::vector<PairOutcome>& pairs,
                       const std::vector<std::optional<QueryResult>>& results, MotionModel model,
                       const std::string& stream_name, json* info) {
  const Plot plot = Layout(o, skeleton, pairs, stream_name);
  const std::vector<TimelineSample> samples = Sample(plot, skeleton, engine, pairs, results, model);
  RgbaImage image(o.width, o.height, kPaper);
  DrawTitle(plot, &image);
  DrawContactBands(plot, pairs, results, &image);
  DrawAxes(plot, &image);
  DrawLinks(plot, skeleton, samples, &image);
  (*info)["contact_marks"] = DrawContactMarks(plot, pairs, results, &image);
  (*info)["width"] = o.width;
  (*info)["height"] = o.height;
  (*info)["plot"] = json::array({plot.x0, plot.y0, plot.x1, plot.y1});
  (*info)["max_separation"] = plot.max_sep;
  (*info)["mark_colour"] = ColourJson(kContactMark);
  (*info)["band_colour"] = ColourJson(kContactBand);
  json sampled = json::array();
  for (const TimelineSample& ts : samples) {
    sampled.push_back({{"t_s", ts.t_s}, {"separation", ts.separation}});
  }
  (*info)["samples"] = sampled;
  return image;
}

}  // namespace sweptccd::gpu
