#pragma once
// The timeline picture of `sweptccd render`: each link's separation from the
// environment against time over a whole pose stream, pairs with contact as
// bands, first contacts marked. Drawn on the CPU (raster_image.h), no GL.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/query/ccd_query.h"
#include "render/raster_image.h"

namespace sweptccd::gpu {

struct TimelineOptions {
  int width = 1280, height = 720;  // Pixels.
  double max_separation_m = 0.5;   // Separations are clamped here (> 0).
};

/// Draws the timeline of `pairs` (the stream's records, in order) with
/// `results[k]` the answer of every valid pair k (unset for invalid ones).
/// Separations come from engine.Separation at s = 0 of every valid pair, at
/// its first contact, and at s = 1 of the last one. Fills `info` with the
/// plot box, colours, contact marks (pixels) and the samples. Throws
/// InputError (naming `stream_name`) when no pair is valid, or when the size
/// cannot hold the plot and the legend. Pure apart from `info`.
RgbaImage DrawTimeline(const TimelineOptions& options, const Skeleton& skeleton,
                       const CcdEngine& engine, const std::vector<PairOutcome>& pairs,
                       const std::vector<std::optional<QueryResult>>& results, MotionModel model,
                       const std::string& stream_name, nlohmann::json* info);

}  // namespace sweptccd::gpu
