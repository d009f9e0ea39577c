// tirstrain.track: the flow/ tracker over a list of NumPy frames or an image sequence on disk, as
// `tirstrain track --grid` drives it (apps/tirstrain/cmd_track.cpp), returning arrays instead of a CSV.
#include <pybind11/stl.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"
#include "core/error.hpp"
#include "core/scene.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "python/arrays.hpp"
#include "python/bindings.hpp"

namespace tirstrain::python {

namespace {

// Tracks per frame, filled with the GIL released.
struct TrackRun {
  std::vector<Vec2> reference_px;    // [K]
  std::vector<double> position_px;   // [N, K, 2], NaN where not alive
  std::vector<std::int8_t> status;   // [N, K]
  std::vector<std::string> skipped;  // one note per frame of a file source that could not be decoded
  std::size_t frames = 0;
};

// The next frame (image and time) or nothing at the end; called with the GIL released.
using NextFrame = std::function<std::optional<capture::Frame>()>;

cv::Rect checked_roi(const std::vector<int>& v, const cv::Size& frame) {
  if (v.size() != 4 || v[2] <= 0 || v[3] <= 0 || v[0] < 0 || v[1] < 0)
    throw Error("expected x,y,w,h with w, h > 0", {.key = "roi"});
  const cv::Rect r(v[0], v[1], v[2], v[3]);
  if ((r & cv::Rect(0, 0, frame.width, frame.height)) != r)
    throw Error("the ROI " + std::to_string(v[0]) + "," + std::to_string(v[1]) + "," + std::to_string(v[2]) +
                    "," + std::to_string(v[3]) + " does not fit in the " + std::to_string(frame.width) + "x" +
                    std::to_string(frame.height) + " frame",
                {.key = "roi"});
  return r;
}

// The grid of `tirstrain track --grid`: a margin of the refinement subset keeps every point's subset whole.
std::vector<Vec2> grid_points(const cv::Rect& r, double step_px, const flow::TrackerOptions& settings) {
  const double margin =
      settings.refine ? settings.main_match.subset_radius_px + 2.0 : settings.prediction.window_px / 2.0;
  std::vector<Vec2> points;
  for (double y = r.y + margin; y <= r.y + r.height - 1 - margin; y += step_px)
    for (double x = r.x + margin; x <= r.x + r.width - 1 - margin; x += step_px) points.push_back({x, y});
  if (points.empty())
    throw Error("the grid has no point at least " + std::to_string(static_cast<int>(margin)) +
                    " px inside the tracked region",
                {.key = "grid_px"});
  return points;
}

void record(const flow::FeatureTracker& tracker, TrackRun& run) {
  for (const flow::Track& t : tracker.tracks()) {
    const bool alive = flow::is_alive(t.status);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    run.position_px.push_back(alive ? t.position_px.x : nan);
    run.position_px.push_back(alive ? t.position_px.y : nan);
    // As /tracks/status: the reason in the frame of retirement only, −1 after (docs/formats.md).
    const bool retired_before =
        !alive && t.retired_frame >= 0 && static_cast<std::size_t>(t.retired_frame) < run.frames;
    run.status.push_back(retired_before ? std::int8_t{-1} : static_cast<std::int8_t>(t.status));
  }
  ++run.frames;
}

TrackRun run_tracker(const NextFrame& next, const std::string& origin, double grid_px,
                     const std::optional<std::vector<int>>& roi, const std::string& preset,
                     const std::optional<std::string>& scene_path) {
  Scene scene;
  if (scene_path) scene = load_scene(*scene_path);
  flow::TrackerOptions settings = flow::parse_tracking_options(scene, preset);
  settings.births.enabled = false;  // the grid is tracked as it is; K stays fixed
  std::optional<capture::Frame> first = next();
  if (!first) throw Error("the sequence has no frames", {.file = origin});
  const cv::Size size = first->image.size();
  cv::Rect region(0, 0, size.width, size.height);
  cv::Mat mask;
  if (roi) {
    region = checked_roi(*roi, size);
    mask = cv::Mat::zeros(size, CV_8U);
    mask(region).setTo(1);
  }
  flow::FeatureTracker tracker(settings);
  try {
    tracker.start(first->image, mask, first->device_time_s, grid_points(region, grid_px, settings));
  } catch (const Error& e) {
    if (!e.context().key.empty()) throw;
    throw Error(e.message(), {.file = origin, .frame = 0});
  }
  TrackRun run;
  for (const flow::Track& t : tracker.tracks()) run.reference_px.push_back(t.reference_px);
  record(tracker, run);
  while (std::optional<capture::Frame> f = next()) {
    if (f->status == capture::FrameStatus::kCorrupt || f->status == capture::FrameStatus::kIncomplete) {
      run.skipped.push_back("skipping frame " + std::to_string(f->index) + " (" +
                            capture::to_string(f->status) + ")");
      continue;
    }
    try {
      tracker.track(f->image, mask, f->device_time_s);
    } catch (const Error& e) {
      throw Error(e.message(), {.file = origin, .frame = f->index});
    }
    record(tracker, run);
  }
  return run;
}

py::tuple to_python(const TrackRun& run) {
  const auto k = static_cast<py::ssize_t>(run.reference_px.size());
  const auto n = static_cast<py::ssize_t>(run.frames);
  auto reference = new_array<double>({k, 2});
  for (py::ssize_t i = 0; i < k; ++i) {
    reference.mutable_at(i, 0) = run.reference_px[static_cast<std::size_t>(i)].x;
    reference.mutable_at(i, 1) = run.reference_px[static_cast<std::size_t>(i)].y;
  }
  auto position = new_array<double>({n, k, 2});
  std::copy(run.position_px.begin(), run.position_px.end(), position.mutable_data());
  auto status = new_array<std::int8_t>({n, k});
  std::copy(run.status.begin(), run.status.end(), status.mutable_data());
  return py::make_tuple(reference, position, status);
}

py::tuple track(const py::object& frames, double grid_px, const std::optional<std::vector<int>>& roi,
                const std::string& preset, const std::optional<std::string>& scene) {
  if (!(grid_px >= 1.0 && grid_px <= 1e4)) throw Error("must be in [1, 10000] px", {.key = "grid_px"});
  TrackRun run;
  if (py::isinstance<py::str>(frames) || py::hasattr(frames, "__fspath__")) {
    const std::string path = py::str(py::module_::import("os").attr("fspath")(frames));
    py::gil_scoped_release release;
    std::unique_ptr<capture::FrameSource> source = capture::open_source(path);
    run = run_tracker([&] { return source->next(); }, path, grid_px, roi, preset, scene);
  } else {
    // Views on the caller's arrays, taken while the GIL is held; the list keeps them alive.
    std::vector<ImageView> views;
    for (const py::handle item : frames)
      views.push_back(image_view(item, "frames[" + std::to_string(views.size()) + "]"));
    std::size_t at = 0;
    const auto next = [&]() -> std::optional<capture::Frame> {
      if (at == views.size()) return std::nullopt;
      capture::Frame f;
      f.image = views[at].mat;
      f.index = static_cast<std::int64_t>(at);
      f.device_time_s = static_cast<double>(at);  // no clock: one second per frame
      ++at;
      return f;
    };
    py::gil_scoped_release release;
    run = run_tracker(next, "frames", grid_px, roi, preset, scene);
  }
  if (!run.skipped.empty()) {
    const py::object warn = py::module_::import("warnings").attr("warn");
    for (const std::string& note : run.skipped) warn("tirstrain.track: " + note);
  }
  return to_python(run);
}

}  // namespace

void bind_flow(py::module_& m) {
  using namespace py::literals;
  m.def(
      "track", &track, "frames"_a, py::kw_only(), "grid_px"_a, "roi"_a = py::none(), "preset"_a = "auto",
      "scene"_a = py::none(),
      "Tracks a grid of points (spacing grid_px, px) through the frames with the flow/ tracker, as\n"
      "`tirstrain track --grid` does. frames: a list of 2-D NumPy arrays (uint8, uint16 or float32 with\n"
      "full scale 1, one size), or a path (image folder, printf/glob pattern or video file). roi: (x, y, w,\n"
      "h) px, the region the grid fills and the tracker works in. preset: auto or delhaye2016. scene: a\n"
      "scene file (its tracking: section). Returns (reference_px [K, 2], position_px [N, K, 2] with NaN\n"
      "where a track is not alive, status [N, K] int8: 0-9 alive, >= 10 the reason it was retired in the\n"
      "frame it was retired, -1 in the frames after; docs/formats.md /tracks/status). Frames of a file "
      "source that cannot be decoded are skipped with\n"
      "a warning and have no row.");
}

}  // namespace tirstrain::python
