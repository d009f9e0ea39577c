#include "samples/synth_config.hpp"

#include <cmath>
#include <limits>

#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::samples {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A fixed-length list of numbers, e.g. `translation_px: [3.5, -1]`.
std::vector<double> fixed_numbers(YamlSection& section, const std::string& key, std::size_t count,
                                  const std::vector<double>& fallback) {
  std::vector<double> values = section.numbers(key, fallback);
  if (values.size() != count)
    throw Error("expected a list of " + std::to_string(count) + " numbers",
                {.file = section.file(), .key = section.path_of(key)});
  return values;
}

Vec2 vec2(YamlSection& section, const std::string& key, Vec2 fallback) {
  const auto v = fixed_numbers(section, key, 2, {fallback.x, fallback.y});
  return {v[0], v[1]};
}

void parse_contact(YamlSection s, ContactConfig& c) {
  c.shape = s.choice("shape", "hertz", {"hertz", "ellipse"}) == "hertz" ? ContactShape::kHertz
                                                                        : ContactShape::kEllipse;
  c.normal_N = s.number("normal_N", c.normal_N, 1e-4, 1e3);
  c.radius_m = s.number("radius_m", c.radius_m, 1e-4, 1.0);
  if (c.shape == ContactShape::kEllipse) {
    const auto axes = fixed_numbers(s, "semi_axes_mm", 2, {c.semi_axes_mm[0], c.semi_axes_mm[1]});
    for (double a : axes)
      if (!(a > 0.01 && a < 1000.0))
        throw Error("semi-axes must lie in (0.01, 1000) mm",
                    {.file = s.file(), .key = s.path_of("semi_axes_mm")});
    c.semi_axes_mm[0] = axes[0];
    c.semi_axes_mm[1] = axes[1];
    c.angle_deg = s.number("angle_deg", 0.0, -360.0, 360.0);
  }
  if (s.has("centre_px")) c.centre_px = vec2(s, "centre_px", {});
  c.border_irregularity = s.number("border_irregularity", c.border_irregularity, 0.0, 0.2);
  c.border_softness_px = s.number("border_softness_px", c.border_softness_px, 0.0, 50.0);
  c.fade_mm = s.number("fade_mm", c.fade_mm, 0.0, 10.0);
  c.fade_floor = s.number("fade_floor", c.fade_floor, 0.0, 1.0);
  s.finish();
}

void parse_loading(YamlSection s, LoadingConfig& l) {
  const std::string field =
      s.choice("field", "cattaneo_mindlin", {"cattaneo_mindlin", "rigid", "affine", "none"});
  l.field = field == "cattaneo_mindlin" ? FieldKind::kCattaneoMindlin
            : field == "rigid"          ? FieldKind::kRigid
            : field == "affine"         ? FieldKind::kAffine
                                        : FieldKind::kNone;
  l.direction_deg = s.number("direction_deg", l.direction_deg, -360.0, 360.0);
  l.shear_start_s = s.number("shear_start_s", l.shear_start_s, 0.0, 1e4);
  if (l.field == FieldKind::kCattaneoMindlin) {
    l.friction = s.number("friction", l.friction, 0.01, 10.0);
    l.plate_speed_mm_s = s.number("plate_speed_mm_s", l.plate_speed_mm_s, 0.0, 1e3);
  }
  if (l.field == FieldKind::kRigid || l.field == FieldKind::kAffine)
    l.translation_px = vec2(s, "translation_px", {});
  if (l.field == FieldKind::kRigid) l.rotation_deg = s.number("rotation_deg", 0.0, -90.0, 90.0);
  if (l.field == FieldKind::kAffine) {
    if (!s.has("gradient"))
      throw Error("required key is missing (affine field: [H_xx, H_xy, H_yx, H_yy] at the last frame)",
                  {.file = s.file(), .key = s.path_of("gradient")});
    const auto h = fixed_numbers(s, "gradient", 4, {});
    l.gradient = {h[0], h[1], h[2], h[3]};
    // F = I + H must keep its orientation along the whole ramp, or the map is not invertible.
    for (double t = 0.0; t <= 1.0; t += 1.0 / 64.0) {
      const double det = (1.0 + t * h[0]) * (1.0 + t * h[3]) - t * t * h[1] * h[2];
      if (det < 0.05)
        throw Error("the deformation gradient I + H folds the skin (det F < 0.05 along the ramp)",
                    {.file = s.file(), .key = s.path_of("gradient")});
    }
  }
  s.finish();
}

void parse_fingerprint(YamlSection s, FingerprintConfig& f) {
  f.core_offset_mm = vec2(s, "core_offset_mm", f.core_offset_mm);
  f.axis_deg = s.number("axis_deg", f.axis_deg, -360.0, 360.0);
  f.loop_length_mm = s.number("loop_length_mm", f.loop_length_mm, 0.0, 100.0);
  if (s.has("delta_offset_mm")) f.delta_offset_mm = vec2(s, "delta_offset_mm", {});
  f.minutiae_per_mm2 = s.number("minutiae_per_mm2", f.minutiae_per_mm2, 0.0, 2.0);
  f.flow_warp = s.number("flow_warp", f.flow_warp, 0.0, 3.0);
  if (s.has("background")) f.background = s.number("background", 0.8, 0.0, 1.0);
  f.ridge_contrast = s.number("ridge_contrast", f.ridge_contrast, 0.0, 1.0);
  f.vignetting = s.number("vignetting", f.vignetting, 0.0, 0.9);
  f.pore_depth = s.number("pore_depth", f.pore_depth, 0.0, 1.0);
  f.pore_spacing_mm = s.number("pore_spacing_mm", f.pore_spacing_mm, 0.02, 10.0);
  f.pore_sigma_mm = s.number("pore_sigma_mm", f.pore_sigma_mm, 0.005, 5.0);
  s.finish();
}

void parse_pattern(YamlSection s, PatternConfig& p) {
  p.dot_spacing_mm = s.number("dot_spacing_mm", p.dot_spacing_mm, 0.02, 10.0);
  p.dot_sigma_mm = s.number("dot_sigma_mm", p.dot_sigma_mm, 0.005, 5.0);
  p.opacity = s.number("opacity", p.opacity, 0.0, 1.0);
  p.fill = s.number("fill", p.fill, 0.0, 1.0);
  s.finish();
}

void parse_sweat(YamlSection s, SweatConfig& w) {
  w.blobs = static_cast<int>(s.integer("blobs", w.blobs, 0, 1000));
  w.radius_mm_min = s.number("radius_mm_min", w.radius_mm_min, 0.01, 20.0);
  w.radius_mm_max = s.number("radius_mm_max", w.radius_mm_max, 0.01, 20.0);
  if (w.radius_mm_max < w.radius_mm_min)
    throw Error("must not be smaller than radius_mm_min",
                {.file = s.file(), .key = s.path_of("radius_mm_max")});
  w.depth = s.number("depth", w.depth, 0.0, 1.0);
  s.finish();
}

void parse_sensor(YamlSection s, SensorConfig& c, int frames) {
  c.full_well_electrons = s.number("full_well_electrons", c.full_well_electrons, 0.0, 1e9);
  c.read_noise = s.number("read_noise", c.read_noise, 0.0, 1.0);
  c.blur_sigma_px = s.number("blur_sigma_px", c.blur_sigma_px, 0.0, 50.0);
  c.drift = s.number("drift", c.drift, -0.9, 10.0);
  c.gain = s.number("gain", c.gain, 0.01, 100.0);
  for (double v : s.numbers("motion_blur_frames", {})) {
    if (v != std::floor(v) || v < 0 || v >= frames)
      throw Error("expected frame indices in [0, " + std::to_string(frames - 1) + "]",
                  {.file = s.file(), .key = s.path_of("motion_blur_frames")});
    c.motion_blur_frames.push_back(static_cast<int>(v));
  }
  c.motion_blur_exposure_s = s.number("motion_blur_exposure_s", c.motion_blur_exposure_s, 0.0, 10.0);
  s.finish();
}

void parse_channels(YamlSection s, ChannelsConfig& c) {
  c.rate_hz = s.number("rate_hz", c.rate_hz, 10.0, 1e6);
  c.normal_noise_N = s.number("normal_noise_N", c.normal_noise_N, 0.0, 100.0);
  c.tangential_noise_N = s.number("tangential_noise_N", c.tangential_noise_N, 0.0, 100.0);
  c.slip_fluctuation_N = s.number("slip_fluctuation_N", c.slip_fluctuation_N, 0.0, 100.0);
  YamlSection a = s.section("accelerometer");
  c.accelerometer.mass_kg = a.number("mass_kg", c.accelerometer.mass_kg, 1e-6, 100.0);
  c.accelerometer.damping_N_s_m = a.number("damping_N_s_m", c.accelerometer.damping_N_s_m, 0.0, 1e6);
  c.accelerometer.stiffness_N_m = a.number("stiffness_N_m", c.accelerometer.stiffness_N_m, 1e-3, 1e9);
  c.accelerometer.noise_m_s2 = a.number("noise_m_s2", c.accelerometer.noise_m_s2, 0.0, 1e4);
  a.finish();
  s.finish();
}

}  // namespace

SynthConfig parse_synth_config(const Scene& scene) {
  SynthConfig cfg;
  cfg.scene = scene;
  const std::string& file = scene.file;
  if (scene.synthesis.empty())
    throw Error("required key is missing (the synthesis section describes the trial to render)",
                {.file = file, .key = "synthesis"});
  YamlSection top(scene.synthesis, file, "synthesis");
  // Up to 2^53: truth.h5 keeps the seed as a double, which holds every integer up to there exactly.
  cfg.seed = static_cast<std::uint64_t>(top.integer("seed", 1, 0, 1L << 53));

  YamlSection image = top.section("image");
  cfg.image.width_px = static_cast<int>(image.integer("width_px", 0, 16, 8192));
  cfg.image.height_px = static_cast<int>(image.integer("height_px", 0, 16, 8192));
  if (!image.has("width_px")) image.required_number("width_px");
  if (!image.has("height_px")) image.required_number("height_px");
  const long depth = image.integer("bit_depth", 8, 8, 16);
  if (depth != 8 && depth != 16)
    throw Error("bit depth must be 8 or 16", {.file = file, .key = image.path_of("bit_depth")});
  cfg.image.bit_depth = static_cast<int>(depth);
  image.finish();

  YamlSection timing = top.section("timing");
  if (!timing.has("frames")) timing.required_number("frames");
  cfg.timing.frames = static_cast<int>(timing.integer("frames", 0, 1, 100000));
  cfg.timing.frame_rate_hz = timing.required_number("frame_rate_hz", 1e-3, 1e6);
  cfg.timing.jitter_s = timing.number("jitter_s", 0.0, 0.0, 0.1 / cfg.timing.frame_rate_hz);
  timing.finish();

  parse_contact(top.section("contact"), cfg.contact);
  parse_loading(top.section("loading"), cfg.loading);
  parse_fingerprint(top.section("fingerprint"), cfg.fingerprint);
  parse_pattern(top.section("pattern"), cfg.pattern);
  parse_sweat(top.section("sweat"), cfg.sweat);
  parse_sensor(top.section("sensor"), cfg.sensor, cfg.timing.frames);
  parse_channels(top.section("channels"), cfg.channels);
  YamlSection truth = top.section("truth");
  cfg.truth.grid_step_px = truth.number("grid_step_px", cfg.truth.grid_step_px, 1.0, 1024.0);
  cfg.truth.orientation_block_px =
      static_cast<int>(truth.integer("orientation_block_px", cfg.truth.orientation_block_px, 4, 1024));
  truth.finish();
  top.finish();

  cfg.ridge_period_mm = scene.ridge_period_mm.value_or(0.45);
  cfg.ridges_dark = scene.ridge_polarity != "bright";

  if (scene.reference_pattern_roi) {
    const RoiPx& r = *scene.reference_pattern_roi;
    if (r.x + r.width > cfg.image.width_px || r.y + r.height > cfg.image.height_px)
      throw Error("the reference pattern band does not fit in the " + std::to_string(cfg.image.width_px) +
                      "x" + std::to_string(cfg.image.height_px) + " image",
                  {.file = file, .key = "reference_pattern.roi_px"});
  }
  if (cfg.contact.centre_px) {
    const Vec2 c = *cfg.contact.centre_px;
    if (c.x < 0 || c.y < 0 || c.x > cfg.image.width_px - 1 || c.y > cfg.image.height_px - 1)
      throw Error("the contact centre lies outside the image",
                  {.file = file, .key = "synthesis.contact.centre_px"});
  }
  return cfg;
}

SynthConfig load_synth_config(const std::string& path) {
  return parse_synth_config(load_scene(path));
}

}  // namespace tirstrain::samples
