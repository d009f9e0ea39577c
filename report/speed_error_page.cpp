#include "report/speed_error_page.hpp"

#include <cmath>

#include "report/html_page.hpp"

namespace tirstrain::report {
namespace {

using nlohmann::json;

bool drawable(const SpeedErrorPoint& p) {
  return std::isfinite(p.frames_per_s) && std::isfinite(p.strain_rms) && p.frames_per_s > 0 &&
         p.strain_rms > 0;
}

// A point is on its scene's Pareto front when no other point of the scene is at least as fast and as
// accurate, and better in one of the two.
bool on_front(const SpeedErrorPoint& a, const std::vector<SpeedErrorPoint>& points) {
  for (const SpeedErrorPoint& b : points) {
    if (&b == &a || b.scene != a.scene || !drawable(b)) continue;
    if (b.frames_per_s >= a.frames_per_s && b.strain_rms <= a.strain_rms &&
        (b.frames_per_s > a.frames_per_s || b.strain_rms < a.strain_rms))
      return false;
  }
  return true;
}

json panel_spec(json rows) {
  const json x = {{"field", "frames_per_s"},
                  {"type", "quantitative"},
                  {"scale", {{"type", "log"}}},
                  {"title", "frames/s (log)"}};
  const json y = {{"field", "strain_rms"},
                  {"type", "quantitative"},
                  {"scale", {{"type", "log"}}},
                  {"title", "strain RMS error (dimensionless, log)"}};
  const json tooltip = json::array({{{"field", "scene"}},
                                    {{"field", "config"}},
                                    {{"field", "frames_per_s"}, {"title", "frames/s"}},
                                    {{"field", "strain_rms"}, {"title", "strain RMS"}},
                                    {{"field", "front"}, {"title", "on the front"}}});
  json front = {{"transform", json::array({{{"filter", "datum.front"}}})},
                {"mark", {{"type", "line"}, {"color", "#f58518"}, {"strokeWidth", 2}}},
                {"encoding", {{"x", x}, {"y", y}, {"order", {{"field", "frames_per_s"}}}}}};
  json dots = {{"mark", {{"type", "point"}, {"filled", true}, {"size", 70}}},
               {"encoding",
                {{"x", x},
                 {"y", y},
                 {"color", {{"field", "config"}, {"type", "nominal"}}},
                 {"shape", {{"field", "front"}, {"type", "nominal"}, {"title", "on the Pareto front"}}},
                 {"tooltip", tooltip}}}};
  json labels = {{"mark", {{"type", "text"}, {"align", "left"}, {"dx", 7}, {"dy", -6}, {"fontSize", 10}}},
                 {"encoding", {{"x", x}, {"y", y}, {"text", {{"field", "config"}}}}}};
  return {{"data", {{"values", std::move(rows)}}},
          {"facet", {{"column", {{"field", "scene"}, {"type", "nominal"}, {"title", nullptr}}}}},
          {"resolve", {{"scale", {{"x", "independent"}, {"y", "independent"}}}}},
          {"spec", {{"width", 360}, {"height", 300}, {"layer", json::array({front, dots, labels})}}}};
}

}  // namespace

std::string speed_error_page(const std::vector<SpeedErrorPoint>& points, const std::string& caption_note) {
  json rows = json::array();
  std::size_t left_out = 0;
  for (const SpeedErrorPoint& p : points) {
    if (!drawable(p)) {
      ++left_out;
      continue;
    }
    rows.push_back({{"scene", p.scene},
                    {"config", p.config},
                    {"frames_per_s", rounded(p.frames_per_s)},
                    {"strain_rms", rounded(p.strain_rms)},
                    {"front", on_front(p, points)}});
  }
  Figure f;
  f.id = "speed-error";
  f.title = "Speed against strain error";
  f.caption =
      "Each configuration's end-to-end frames/s against its strain RMS error over the trial (pooled "
      "components, dimensionless), both on log axes, one panel per scene; the orange line joins the "
      "Pareto front, where no other configuration is both faster and more accurate." +
      (left_out ? " " + std::to_string(left_out) + " run(s) without a finite speed or error are not drawn."
                : "") +
      (caption_note.empty() ? "" : " " + caption_note);
  f.spec = panel_spec(std::move(rows));
  Page page;
  page.title = "tirstrain bench: speed against error";
  page.figures.push_back(std::move(f));
  return render_page(page);
}

}  // namespace tirstrain::report
