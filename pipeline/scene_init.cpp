#include "pipeline/scene_init.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <vector>

#include "capture/file_sources.hpp"
#include "capture/frame_source.hpp"
#include "contact/pattern_band.hpp"
#include "contact/segmenter.hpp"
#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "core/median.hpp"

namespace tirstrain::pipeline {
namespace {

std::optional<double> rate_from(std::vector<double> times_s) {
  if (times_s.size() < 2) return std::nullopt;
  std::vector<double> intervals;
  for (std::size_t i = 1; i < times_s.size(); ++i) intervals.push_back(times_s[i] - times_s[i - 1]);
  const double median = upper_median_in_place(intervals);
  if (!(median > 0.0)) return std::nullopt;
  return 1.0 / median;
}

std::string number(double v, const char* format = "%.4g") {
  char text[64];
  std::snprintf(text, sizeof text, format, v);
  return text;
}

}  // namespace

SceneSurvey survey_recording(const SceneInitOptions& options) {
  SceneSurvey survey;
  std::unique_ptr<capture::FrameSource> source =
      capture::open_source(options.input, capture::FileSourceOptions{.frame_rate_Hz = options.frame_rate_Hz});
  const auto settings = source->settings();
  const bool time_measured = settings.count("time_measured") == 0 || settings.at("time_measured") == "true";
  survey.time_source = settings.count("time_source") ? settings.at("time_source") : "source timestamps";
  std::optional<contact::ContactSegmenter> segmenter;
  std::vector<double> times_s;
  int dark = 0, bright = 0;
  while (survey.frames_read < options.max_frames) {
    std::optional<capture::Frame> frame = source->next();
    if (!frame) break;
    ++survey.frames_read;
    if (frame->image.empty() || frame->status == capture::FrameStatus::kCorrupt) continue;
    times_s.push_back(frame->device_time_s);
    if (!segmenter) {
      survey.width_px = frame->image.cols;
      survey.height_px = frame->image.rows;
      survey.bit_depth = frame->image.depth() == CV_16U ? 16 : 8;
      const contact::PatternBand band = contact::detect_pattern_band(frame->image);
      survey.band_confidence = band.confidence;
      survey.band_edge = contact::to_string(band.edge);
      contact::SegmenterOptions segmentation;
      if (band.edge != contact::ImageEdge::kNone) {
        survey.band_roi_px = RoiPx{band.roi_px.x, band.roi_px.y, band.roi_px.width, band.roi_px.height};
        segmentation.exclude_px = band.roi_px;
      }
      segmenter.emplace(segmentation);
    }
    const contact::ContactResult r = segmenter->segment(frame->image);
    if ((r.status & contact::kNoContact) != 0) continue;
    if (survey.first_contact_frame < 0) survey.first_contact_frame = frame->index;
    if (r.polarity < 0) ++dark;
    if (r.polarity > 0) ++bright;
    if (r.area_mm2 > survey.largest_area_mm2) {
      survey.largest_area_mm2 = r.area_mm2;
      survey.largest_contact_frame = frame->index;
      survey.largest_semi_axes_px[0] = r.ellipse ? r.ellipse->semi_major_px : 0.0;
      survey.largest_semi_axes_px[1] = r.ellipse ? r.ellipse->semi_minor_px : 0.0;
      survey.largest_touches_edge = (r.status & contact::kTouchesEdge) != 0;
    }
  }
  if (!segmenter) throw Error("no frame of the input could be decoded", {.file = options.input});
  if (segmenter->period_measured()) survey.ridge_period_px = segmenter->ridge_period_px();
  if (dark + bright > 0) survey.ridge_polarity = dark >= bright ? "dark" : "bright";
  if (time_measured) survey.frame_rate_hz = rate_from(times_s);
  return survey;
}

std::string scene_init_text(const SceneSurvey& s, const std::string& input) {
  const Scene defaults;
  std::ostringstream out;
  out << "# Starting scene for " << input << ", written by `tirstrain scene init` from what its first "
      << s.frames_read << " frames show.\n"
      << "# Check every value. PLACEHOLDER marks what images cannot tell: it holds the default `tirstrain "
         "process` uses\n# without it, and results are only as right as it is.\n#\n"
      << "# Frames: " << s.width_px << " x " << s.height_px << " px, " << s.bit_depth << "-bit; ";
  if (s.frame_rate_hz) {
    out << "frame rate " << number(*s.frame_rate_hz, "%.5g") << " Hz (median interval of " << s.time_source
        << ").\n";
  } else {
    out << "frame rate unknown (" << s.time_source << ").\n";
  }
  if (s.first_contact_frame >= 0) {
    out << "# Contact: first in frame " << s.first_contact_frame << "; largest in frame "
        << s.largest_contact_frame << ", " << number(s.largest_area_mm2)
        << " mm2 at the placeholder px_per_mm";
    if (s.largest_semi_axes_px[0] > 0.0)
      out << " (ellipse semi-axes " << number(s.largest_semi_axes_px[0], "%.1f") << " x "
          << number(s.largest_semi_axes_px[1], "%.1f") << " px)";
    else
      out << " (no ellipse: too little of its outline is inside the frame)";
    if (s.largest_touches_edge) out << ", cut by the frame's edge";
    out << ".\n";
  } else {
    out << "# Contact: none seen in these frames.\n";
  }
  out << "calibration:\n"
      << "  px_per_mm: " << number(defaults.px_per_mm)
      << "                  # PLACEHOLDER: image scale; measure "
      << "it (e.g. a ruler on the glass)\n";
  if (s.ridge_period_px) {
    out << "  # ridge_period_mm: " << number(*s.ridge_period_px / defaults.px_per_mm, "%.3f")
        << "       # measured " << number(*s.ridge_period_px, "%.1f")
        << " px (divided by the px_per_mm above); left to be measured by each run\n";
  } else {
    out << "  # ridge_period_mm: 0.45        # not measured (no clear ridges seen): each run measures it\n";
  }
  // Without ridges the segmenter still measures the contact's texture against the background: the
  // polarity then says which of the two is darker, not which way ridges appear.
  out << "  ridge_polarity: " << s.ridge_polarity
      << (s.ridge_polarity == "auto" ? "         # not seen: measured by each run\n"
          : s.ridge_period_px
              ? "         # measured: ridges in contact darker (dark) or brighter (bright)\n"
              : "         # measured: the contact's texture darker (dark) or brighter (bright) than the "
                "background; no ridges seen\n");
  out << "tissue:                          # PLACEHOLDERS: the skin's properties for the strain energy\n"
      << "  E_Pa: " << number(defaults.tissue.young_Pa) << "\n"
      << "  nu: " << number(defaults.tissue.poisson) << "\n"
      << "  depth_m: " << number(defaults.tissue.depth_m) << "\n";
  out << "reference_pattern:\n";
  if (s.band_roi_px) {
    const RoiPx& r = *s.band_roi_px;
    out << "  roi_px: [" << r.x << ", " << r.y << ", " << r.width << ", " << r.height
        << "]    # the printed dot band, detected along the " << s.band_edge << " edge (confidence "
        << number(s.band_confidence, "%.2f") << ")\n";
  } else {
    out << "  detect: false                  # no printed dot band found along the edges (best confidence "
        << number(s.band_confidence, "%.2f") << "); give roi_px: [x, y, width, height] if there is one\n";
  }
  out << "compute: [contact, tracking, strain]   # add channels with a channels: section (docs/formats.md)\n";
  return out.str();
}

SceneSurvey write_initial_scene(const SceneInitOptions& options) {
  if (!options.overwrite && std::filesystem::exists(options.out_path))
    throw Error(
        "exists and is not replaced: a scene file may hold a measured calibration; give another "
        "file, or --overwrite",
        {.file = options.out_path, .key = "--out"});
  const SceneSurvey survey = survey_recording(options);
  write_text_file(options.out_path, scene_init_text(survey, options.input));
  // What was written must read back as a scene.
  (void)load_scene(options.out_path);
  return survey;
}

}  // namespace tirstrain::pipeline
