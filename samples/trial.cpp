#include "samples/trial.hpp"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "core/error.hpp"
#include "core/smoothstep.hpp"

namespace tirstrain::samples {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Ridge level of a sweat-wetted patch: the liquid bridges the valleys, so the patch is nearly uniformly in
// contact and the ridge pattern is lost.
constexpr double kWetLevel = 0.75;
constexpr int kMotionBlurSamples = 9;

std::vector<double> make_frame_times(const SynthConfig& c) {
  std::mt19937_64 rng(mix_seed(c.seed, 0x71AEULL));
  std::normal_distribution<double> jitter(0.0, c.timing.jitter_s);
  const double period_s = 1.0 / c.timing.frame_rate_hz;
  std::vector<double> t(static_cast<std::size_t>(c.timing.frames));
  for (std::size_t i = 0; i < t.size(); ++i) {
    // Frame 0 is the reference (t = 0); jitter is clamped to +-0.4 periods so timestamps stay increasing.
    const double j =
        (i == 0 || c.timing.jitter_s == 0.0) ? 0.0 : std::clamp(jitter(rng), -0.4 * period_s, 0.4 * period_s);
    t[i] = static_cast<double>(i) * period_s + j;
  }
  return t;
}

Vec2 core_position(const SynthConfig& c, const LoadHistory& h) {
  const Vec2 centre = h.contact_centre_px();
  return {centre.x + c.fingerprint.core_offset_mm.x * c.scene.px_per_mm,
          centre.y + c.fingerprint.core_offset_mm.y * c.scene.px_per_mm};
}

}  // namespace

Trial::Trial(SynthConfig config)
    : config_(std::move(config)),
      history_(config_),
      frame_times_s_(make_frame_times(config_)),
      fingerprint_(
          config_.fingerprint, config_.scene.px_per_mm, config_.ridge_period_mm,
          core_position(config_, history_),
          {static_cast<double>(config_.image.width_px), static_cast<double>(config_.image.height_px)},
          config_.seed),
      pattern_(config_.pattern, config_.scene.px_per_mm, config_.seed),
      sweat_(config_.sweat, config_.scene.px_per_mm, history_.contact_centre_px(),
             history_.contact_semi_axes_px(), config_.seed) {
  std::mt19937_64 rng(mix_seed(config_.seed, 0xB0DEULL));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 4; ++k) {
    border_coeff_[k] = config_.contact.border_irregularity * u(rng) / (1.0 + 0.5 * k);
    border_phase_[k] = std::numbers::pi * u(rng);
  }
  background_ = config_.fingerprint.background >= 0.0 ? config_.fingerprint.background
                                                      : (config_.ridges_dark ? 0.8 : 0.15);
  const double step = config_.truth.grid_step_px;
  for (double x = 0.0; x <= config_.image.width_px - 1; x += step) grid_x_px_.push_back(x);
  for (double y = 0.0; y <= config_.image.height_px - 1; y += step) grid_y_px_.push_back(y);
  signed_distance_px_.create(height(), width(), CV_64F);
  cv::parallel_for_(cv::Range(0, height()), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < width(); ++x)
        signed_distance_px_.at<double>(y, x) = contact_signed_distance_px({double(x), double(y)});
  });
}

double Trial::contact_signed_distance_px(Vec2 x) const {
  const Vec2 c = history_.contact_centre_px();
  const Vec2 axes = history_.contact_semi_axes_px();
  const double angle = history_.contact_angle_rad();
  const double cs = std::cos(angle), sn = std::sin(angle);
  const double dx = x.x - c.x, dy = x.y - c.y;
  const double nx = (cs * dx + sn * dy) / axes.x, ny = (-sn * dx + cs * dy) / axes.y;
  const double q = std::hypot(nx, ny);
  const double theta = std::atan2(ny, nx);
  double boundary = 1.0;
  for (int k = 0; k < 4; ++k) boundary += border_coeff_[k] * std::cos((k + 2) * theta + border_phase_[k]);
  return (q - boundary) * std::sqrt(axes.x * axes.y);
}

double Trial::contact_weight(Vec2 x) const {
  return edge_weight(contact_signed_distance_px(x));
}

double Trial::edge_weight(double signed_distance_px) const {
  const double soft = config_.contact.border_softness_px;
  if (soft <= 0.0) return signed_distance_px <= 0.0 ? 1.0 : 0.0;
  return 0.5 * std::erfc(signed_distance_px / soft);
}

double Trial::border_fade(double signed_distance_px) const {
  const double fade_px = config_.contact.fade_mm * config_.scene.px_per_mm;
  const double floor = config_.contact.fade_floor;
  return fade_px > 0.0 ? floor + (1.0 - floor) * smoothstep5(-signed_distance_px / fade_px) : 1.0;
}

cv::Mat Trial::contact_mask() const {
  cv::Mat mask(height(), width(), CV_8U);
  for (int y = 0; y < height(); ++y)
    for (int x = 0; x < width(); ++x)
      mask.at<std::uint8_t>(y, x) = signed_distance_px_.at<double>(y, x) <= 0.0 ? 1 : 0;
  return mask;
}

double Trial::illumination(Vec2 x, double t_s) const {
  const double w = width(), h = height();
  const double rx = (x.x - 0.5 * (w - 1)) / (0.5 * w), ry = (x.y - 0.5 * (h - 1)) / (0.5 * h);
  const double vignette = 1.0 - config_.fingerprint.vignetting * 0.5 * (rx * rx + ry * ry);
  const double span_s = history_.last_frame_s();
  const double progress = span_s > 0.0 ? t_s / span_s : 0.0;
  // The drift brightens the whole field and tilts it slightly, as a warming LED does.
  return vignette * (1.0 + config_.sensor.drift * progress * (1.0 + 0.25 * rx));
}

void Trial::render_into(const LoadState& state, cv::Mat& out) const {
  out.create(height(), width(), CV_32F);
  const FrameField field = history_.field_at(state);
  const double contrast = config_.fingerprint.ridge_contrast * (config_.ridges_dark ? -1.0 : 1.0);
  const double opacity = config_.pattern.opacity;
  const std::optional<RoiPx> roi = config_.scene.reference_pattern_roi;
  cv::parallel_for_(cv::Range(0, height()), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* row = out.ptr<float>(y);
      const bool roi_row = roi && y >= roi->y && y < roi->y + roi->height;
      const double* distance_row = signed_distance_px_.ptr<double>(y);
      bool have_previous = false;
      Vec2 previous;
      for (int x = 0; x < width(); ++x) {
        const Vec2 p{double(x), double(y)};
        double value = background_;
        const double s = distance_row[x];
        const double w = edge_weight(s);
        if (w > 1e-7) {
          // Warm start from the left neighbour: the field changes little over one pixel, so Newton needs
          // one or two steps instead of three.
          const FrameField::Inverse inv =
              have_previous ? field.invert(p, {previous.x + 1.0, previous.y}) : field.invert(p);
          previous = inv.reference_px;
          have_previous = true;
          const double fade = border_fade(s);
          const double wet = sweat_.contrast_factor(inv.reference_px);
          const double ridge = wet * fingerprint_.ridge(inv.reference_px) + (1.0 - wet) * kWetLevel;
          value += contrast * w * fade * ridge;
        } else {
          have_previous = false;
        }
        if (roi_row && x >= roi->x && x < roi->x + roi->width)
          value *= 1.0 - opacity * pattern_.darkness({p.x - state.plate_px.x, p.y - state.plate_px.y});
        row[x] = static_cast<float>(value * illumination(p, state.t_s));
      }
    }
  });
}

cv::Mat Trial::render_clean_at(double t_s) const {
  cv::Mat out;
  render_into(history_.at(t_s), out);
  return out;
}

cv::Mat Trial::render_clean(int frame) const {
  const double t = frame_times_s_.at(static_cast<std::size_t>(frame));
  const auto& blurred = config_.sensor.motion_blur_frames;
  if (std::find(blurred.begin(), blurred.end(), frame) == blurred.end() ||
      config_.sensor.motion_blur_exposure_s <= 0.0)
    return render_clean_at(t);
  // The exposure is centred on the frame's timestamp; truth refers to that centre.
  cv::Mat sum = cv::Mat::zeros(height(), width(), CV_32F), sample;
  for (int i = 0; i < kMotionBlurSamples; ++i) {
    const double offset =
        (static_cast<double>(i) / (kMotionBlurSamples - 1) - 0.5) * config_.sensor.motion_blur_exposure_s;
    render_into(history_.at(std::max(0.0, t + offset)), sample);
    sum += sample;
  }
  return sum / static_cast<double>(kMotionBlurSamples);
}

cv::Mat Trial::apply_sensor(const cv::Mat& clean, int frame) const {
  const SensorConfig& s = config_.sensor;
  cv::Mat image = clean.clone();
  if (s.blur_sigma_px > 0.0)
    cv::GaussianBlur(image, image, cv::Size(0, 0), s.blur_sigma_px, s.blur_sigma_px, cv::BORDER_REFLECT);
  std::mt19937_64 rng(mix_seed(config_.seed, 0xA0150000ULL + static_cast<std::uint64_t>(frame)));
  std::normal_distribution<double> normal(0.0, 1.0);
  const double full_scale = config_.image.bit_depth == 16 ? 65535.0 : 255.0;
  cv::Mat out(image.size(), config_.image.bit_depth == 16 ? CV_16U : CV_8U);
  const bool noisy = s.full_well_electrons > 0.0 || s.read_noise > 0.0;
  for (int y = 0; y < image.rows; ++y) {
    const float* in = image.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) {
      double v = s.gain * in[x];
      if (noisy) {
        if (s.full_well_electrons > 0.0) {
          const double electrons = std::max(0.0, v) * s.full_well_electrons;
          v = (electrons + std::sqrt(electrons) * normal(rng)) / s.full_well_electrons;
        }
        if (s.read_noise > 0.0) v += s.read_noise * normal(rng);
      }
      const double level = std::round(std::clamp(v, 0.0, 1.0) * full_scale);
      if (config_.image.bit_depth == 16)
        out.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(level);
      else
        out.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(level);
    }
  }
  return out;
}

cv::Mat Trial::inverse_map(int frame, double* max_residual_px) const {
  const FrameField field = this->field(frame);
  cv::Mat map(height(), width(), CV_64FC2);
  std::vector<double> row_max(static_cast<std::size_t>(height()), 0.0);
  cv::parallel_for_(cv::Range(0, height()), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      auto* row = map.ptr<cv::Vec2d>(y);
      for (int x = 0; x < width(); ++x) {
        const FrameField::Inverse inv = field.invert({double(x), double(y)});
        row[x] = {inv.reference_px.x, inv.reference_px.y};
        row_max[static_cast<std::size_t>(y)] =
            std::max(row_max[static_cast<std::size_t>(y)], inv.residual_px);
      }
    }
  });
  if (max_residual_px) *max_residual_px = *std::max_element(row_max.begin(), row_max.end());
  return map;
}

GridTruth Trial::grid_truth(int frame) const {
  const LoadState state = load(frame);
  const FrameField field = history_.field_at(state);
  const std::size_t nx = grid_x_px_.size(), ny = grid_y_px_.size(), n = nx * ny;
  GridTruth t;
  t.displacement_px.resize(2 * n);
  t.gradient.resize(4 * n);
  t.strain.resize(3 * n);
  t.energy_J_m3.resize(n);
  t.in_contact.resize(n);
  t.in_stick.resize(n);
  const double young = config_.scene.tissue.young_Pa, nu = config_.scene.tissue.poisson;
  for (std::size_t j = 0; j < ny; ++j) {
    for (std::size_t i = 0; i < nx; ++i) {
      const std::size_t k = j * nx + i;
      const Vec2 X{grid_x_px_[i], grid_y_px_[j]};
      const FieldValue v = field.evaluate(X);
      const Strain2 e = green_lagrange(v.gradient);
      t.displacement_px[2 * k] = v.displacement_px.x;
      t.displacement_px[2 * k + 1] = v.displacement_px.y;
      t.gradient[4 * k] = v.gradient.xx;
      t.gradient[4 * k + 1] = v.gradient.xy;
      t.gradient[4 * k + 2] = v.gradient.yx;
      t.gradient[4 * k + 3] = v.gradient.yy;
      t.strain[3 * k] = e.xx;
      t.strain[3 * k + 1] = e.yy;
      t.strain[3 * k + 2] = e.xy;
      t.energy_J_m3[k] = plane_strain_energy_density_J_m3(e, young, nu);
      const bool contact = in_contact({X.x + v.displacement_px.x, X.y + v.displacement_px.y});
      t.in_contact[k] = contact ? 1 : 0;
      bool stick = false;
      if (contact && field.model()) {
        const Vec2 m = field.model_point_m(X);
        stick = std::hypot(m.x, m.y) < state.stick_radius_m;
      } else if (contact && state.tangential_N == 0.0 &&
                 config_.loading.field == FieldKind::kCattaneoMindlin) {
        stick = true;  // no tangential load yet: the whole contact sticks
      }
      t.in_stick[k] = stick ? 1 : 0;
    }
  }
  return t;
}

double Trial::ridge_orientation_rad(const FrameField& field, Vec2 x) const {
  const FrameField::Inverse inv = field.invert(x);
  const double theta = fingerprint_.ridge_orientation_rad(inv.reference_px);
  const Gradient2 h = field.evaluate(inv.reference_px).gradient;
  const double tx = std::cos(theta), ty = std::sin(theta);
  double angle = std::atan2(h.yx * tx + (1.0 + h.yy) * ty, (1.0 + h.xx) * tx + h.xy * ty);
  if (angle < 0.0) angle += std::numbers::pi;
  if (angle >= std::numbers::pi) angle -= std::numbers::pi;
  return angle;
}

Trial::OrientationBlocks Trial::ridge_orientation_blocks(int frame, int block_px) const {
  const FrameField field = this->field(frame);
  const int bx_count = (width() + block_px - 1) / block_px, by_count = (height() + block_px - 1) / block_px;
  OrientationBlocks out;
  out.orientation_rad = cv::Mat::zeros(by_count, bx_count, CV_64F);
  out.coherence = cv::Mat::zeros(by_count, bx_count, CV_64F);
  constexpr int kSamples = 8;
  cv::parallel_for_(cv::Range(0, by_count), [&](const cv::Range& rows) {
    for (int by = rows.start; by < rows.end; ++by) {
      const int y0 = by * block_px, y1 = std::min(height(), y0 + block_px);
      for (int bx = 0; bx < bx_count; ++bx) {
        const int x0 = bx * block_px, x1 = std::min(width(), x0 + block_px);
        double c = 0.0, s = 0.0;
        for (int j = 0; j < kSamples; ++j) {
          // Pixel centres are at integer coordinates: the block spans [x0 - 0.5, x1 - 0.5).
          const double y = y0 - 0.5 + (j + 0.5) * (y1 - y0) / kSamples;
          for (int i = 0; i < kSamples; ++i) {
            const double x = x0 - 0.5 + (i + 0.5) * (x1 - x0) / kSamples;
            const double theta = ridge_orientation_rad(field, {x, y});
            c += std::cos(2.0 * theta);
            s += std::sin(2.0 * theta);
          }
        }
        double mean = 0.5 * std::atan2(s, c);
        if (mean < 0.0) mean += std::numbers::pi;
        if (mean >= std::numbers::pi) mean -= std::numbers::pi;
        out.orientation_rad.at<double>(by, bx) = mean;
        out.coherence.at<double>(by, bx) = std::hypot(c, s) / (kSamples * kSamples);
      }
    }
  });
  return out;
}

ChannelSeries Trial::channels() const {
  const ChannelsConfig& c = config_.channels;
  const double end_s = frame_times_s_.back() + 1.0 / config_.timing.frame_rate_hz;
  const auto n = static_cast<std::size_t>(std::floor(end_s * c.rate_hz)) + 1;
  ChannelSeries s;
  std::mt19937_64 rng(mix_seed(config_.seed, 0xC4A77E1ULL));
  std::normal_distribution<double> normal(0.0, 1.0);
  const double px_per_mm = config_.scene.px_per_mm;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / c.rate_hz;
    const LoadState state = history_.at(t);
    const double fluctuation = state.full_slip ? c.slip_fluctuation_N * normal(rng) : 0.0;
    s.t_s.push_back(t);
    s.pad_force_N.push_back(state.tangential_N + fluctuation);
    s.normal_N.push_back(state.normal_N + c.normal_noise_N * normal(rng));
    s.tangential_N.push_back(state.tangential_N + fluctuation + c.tangential_noise_N * normal(rng));
    s.plate_x_mm.push_back(state.plate_px.x / px_per_mm);
    s.plate_y_mm.push_back(state.plate_px.y / px_per_mm);
  }
  // Pad model m x'' + c x' + k x = F(t), F linear between samples (first-order hold), integrated with RK4 on
  // 16 sub-steps per sample: at 1 kHz and a 27 Hz resonance the integration error is far below 1e-6 relative.
  const AccelerometerConfig& pad = c.accelerometer;
  const auto accel = [&](double x, double v, double f) {
    return (f - pad.damping_N_s_m * v - pad.stiffness_N_m * x) / pad.mass_kg;
  };
  double x = s.pad_force_N.front() / pad.stiffness_N_m, v = 0.0;
  const int substeps = 16;
  const double h = 1.0 / (c.rate_hz * substeps);
  s.accel_m_s2.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    s.accel_m_s2[i] = accel(x, v, s.pad_force_N[i]) + pad.noise_m_s2 * normal(rng);
    if (i + 1 == n) break;
    const double f0 = s.pad_force_N[i], f1 = s.pad_force_N[i + 1];
    for (int k = 0; k < substeps; ++k) {
      const double fa = f0 + (f1 - f0) * k / substeps, fm = f0 + (f1 - f0) * (k + 0.5) / substeps,
                   fb = f0 + (f1 - f0) * (k + 1.0) / substeps;
      const double k1x = v, k1v = accel(x, v, fa);
      const double k2x = v + 0.5 * h * k1v, k2v = accel(x + 0.5 * h * k1x, v + 0.5 * h * k1v, fm);
      const double k3x = v + 0.5 * h * k2v, k3v = accel(x + 0.5 * h * k2x, v + 0.5 * h * k2v, fm);
      const double k4x = v + h * k3v, k4v = accel(x + h * k3x, v + h * k3v, fb);
      x += h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
  }
  return s;
}

}  // namespace tirstrain::samples
