#include "samples/generalisation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <random>

#include "core/error.hpp"

namespace tirstrain::samples {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;

double unit_from_bits(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

// Rigid shifts of the subpixel case: 0.05 ... 0.5 px, each in another direction.
constexpr std::array<double, 5> kSubpixelShiftPx = {0.05, 0.1, 0.2, 0.3, 0.5};
constexpr std::array<double, 5> kSubpixelAngleDeg = {0.0, 135.0, 250.0, 45.0, 300.0};
// The integer case's shifts since frame 0 (frame 0 at rest): frame-to-frame jumps of 8, 11, 12 and 10 px.
constexpr std::array<Vec2, 5> kIntegerShiftPx = {Vec2{0, 0}, Vec2{7, -4}, Vec2{15, 3}, Vec2{4, 8},
                                                 Vec2{-3, 1}};

constexpr double kStepAmplitudePx = 10.0;
constexpr double kStepWidestPx = 200.0;
constexpr double kStepNarrowestPx = 20.0;
constexpr double kStretchFinal = 0.45;
constexpr double kRotationFinalDeg = 10.0;
constexpr double kCreepFirstStepPx = 0.02;
constexpr double kCreepLastStepPx = 0.1;
constexpr double kCreepDirectionDeg = 30.0;

// The speckle's dots: spacing, radius (1/e of the peak) and the saturation gain, chosen so the levels spread
// over most of [0.1, 0.9] around mid-grey (mean 0.45, sd 0.15), as in a sprayed DIC pattern.
constexpr double kSpeckleSpacingPx = 5.0;
constexpr double kSpeckleRadiusPx = 2.5;
constexpr double kSpeckleGain = 1.6;

int default_frames(GeneralisationField field) {
  switch (field) {
    case GeneralisationField::kSubpixelShift:
      return 1 + static_cast<int>(kSubpixelShiftPx.size());
    case GeneralisationField::kIntegerShift:
      return static_cast<int>(kIntegerShiftPx.size());
    case GeneralisationField::kChirp:
      return 2;
    case GeneralisationField::kStep:
      return 6;
    case GeneralisationField::kStretch:
    case GeneralisationField::kRotation:
    case GeneralisationField::kCreep:
      return 11;
  }
  return 2;
}

int max_frames(GeneralisationField field) {
  switch (field) {
    case GeneralisationField::kSubpixelShift:
    case GeneralisationField::kIntegerShift:
      return default_frames(field);
    default:
      return 1000;
  }
}

Vec2 centre_of(const GeneralisationConfig& c) {
  return {0.5 * (c.width_px - 1), 0.5 * (c.height_px - 1)};
}

FieldValue translation(Vec2 shift_px) {
  return {shift_px, {}};
}

// u = A (X - c) with H = A.
FieldValue linear(const Gradient2& h, Vec2 X, Vec2 c) {
  const double dx = X.x - c.x, dy = X.y - c.y;
  return {{h.xx * dx + h.xy * dy, h.yx * dx + h.yy * dy}, h};
}

}  // namespace

const std::vector<GeneralisationField>& generalisation_fields() {
  static const std::vector<GeneralisationField> fields = {
      GeneralisationField::kSubpixelShift, GeneralisationField::kIntegerShift, GeneralisationField::kChirp,
      GeneralisationField::kStep,          GeneralisationField::kStretch,      GeneralisationField::kRotation,
      GeneralisationField::kCreep};
  return fields;
}

std::string to_string(GeneralisationField field) {
  switch (field) {
    case GeneralisationField::kSubpixelShift:
      return "subpixel_shift";
    case GeneralisationField::kIntegerShift:
      return "integer_shift";
    case GeneralisationField::kChirp:
      return "chirp";
    case GeneralisationField::kStep:
      return "step";
    case GeneralisationField::kStretch:
      return "stretch";
    case GeneralisationField::kRotation:
      return "rotation";
    case GeneralisationField::kCreep:
      return "creep";
  }
  return "?";
}

std::string to_string(GeneralisationTexture texture) {
  return texture == GeneralisationTexture::kSpeckle ? "speckle" : "fingerprint";
}

GeneralisationField generalisation_field_from_string(const std::string& name) {
  for (GeneralisationField f : generalisation_fields())
    if (to_string(f) == name) return f;
  throw Error("unknown generalisation case '" + name +
              "' (known: subpixel_shift, integer_shift, chirp, step, stretch, rotation, creep)");
}

GeneralisationTexture generalisation_texture_from_string(const std::string& name) {
  if (name == "speckle") return GeneralisationTexture::kSpeckle;
  if (name == "fingerprint") return GeneralisationTexture::kFingerprint;
  throw Error("unknown generalisation texture '" + name + "' (known: speckle, fingerprint)");
}

Speckle::Speckle(double spacing_px, double dot_radius_px, std::uint64_t seed)
    : spacing_px_(spacing_px), inv_radius2_(1.0 / (dot_radius_px * dot_radius_px)), seed_(seed) {}

double Speckle::level(Vec2 X_px) const {
  // Each lattice cell holds one dot, jittered within its cell; cells more than three away from X's cell
  // are at least 3 spacings (15 px, exp(-36) at r = 2.5 px) away and left out.
  const auto cx = static_cast<std::int64_t>(std::floor(X_px.x / spacing_px_));
  const auto cy = static_cast<std::int64_t>(std::floor(X_px.y / spacing_px_));
  double sum = 0.0;
  for (std::int64_t j = cy - 3; j <= cy + 3; ++j) {
    for (std::int64_t i = cx - 3; i <= cx + 3; ++i) {
      const std::uint64_t cell =
          mix_seed(seed_, (static_cast<std::uint64_t>(j) << 32) ^ static_cast<std::uint64_t>(i & 0xFFFFFFFF));
      const double px = (static_cast<double>(i) + unit_from_bits(cell)) * spacing_px_;
      const double py = (static_cast<double>(j) + unit_from_bits(mix_seed(cell, 1))) * spacing_px_;
      const double amplitude = 0.5 + 0.5 * unit_from_bits(mix_seed(cell, 2));
      const double dx = X_px.x - px, dy = X_px.y - py;
      sum += amplitude * std::exp(-(dx * dx + dy * dy) * inv_radius2_);
    }
  }
  return 0.9 - 0.8 * (1.0 - std::exp(-kSpeckleGain * sum));
}

struct GeneralisationCase::Texture {
  std::optional<Speckle> speckle;
  std::optional<Fingerprint> fingerprint;
};

GeneralisationConfig generalisation_config(GeneralisationField field, GeneralisationTexture texture,
                                           double noise_fraction, bool small) {
  GeneralisationConfig c;
  c.field = field;
  c.texture = texture;
  c.noise_fraction = noise_fraction;
  const bool chirp = field == GeneralisationField::kChirp;
  if (small) {
    c.width_px = chirp ? 512 : 192;
    c.height_px = chirp ? 96 : 128;
    c.frames = std::min(default_frames(field), 6);
    c.chirp_max_wavelength_px = 200.0;
    c.chirp_min_wavelength_px = 10.0;
  } else {
    c.width_px = chirp ? 2048 : 512;
    c.height_px = chirp ? 160 : 256;
  }
  return c;
}

GeneralisationCase::GeneralisationCase(GeneralisationConfig config)
    : config_(config), texture_(std::make_unique<Texture>()) {
  frames_ = config_.frames > 0 ? config_.frames : default_frames(config_.field);
  if (frames_ < 2 || frames_ > max_frames(config_.field))
    throw Error("the " + to_string(config_.field) + " case takes 2 to " +
                std::to_string(max_frames(config_.field)) + " frames, not " + std::to_string(frames_));
  if (config_.width_px < 32 || config_.height_px < 32)
    throw Error("generalisation frames are at least 32 x 32 px");
  if (!(config_.noise_fraction >= 0.0 && config_.noise_fraction < 0.5))
    throw Error("the noise is a fraction of full scale in [0, 0.5)");
  if (!(config_.chirp_min_wavelength_px > 2.0 &&
        config_.chirp_max_wavelength_px > config_.chirp_min_wavelength_px))
    throw Error("the chirp's wavelengths need max > min > 2 px");
  const std::uint64_t texture_seed = mix_seed(config_.seed, 0x7E47ULL);
  if (config_.texture == GeneralisationTexture::kSpeckle) {
    texture_->speckle.emplace(kSpeckleSpacingPx, kSpeckleRadiusPx, texture_seed);
  } else {
    // The whole frame is skin in contact: the core at its centre, period 0.45 mm at 52 px/mm (23.4 px).
    texture_->fingerprint.emplace(FingerprintConfig{}, 52.0, 0.45, centre_of(config_),
                                  Vec2{double(config_.width_px), double(config_.height_px)}, texture_seed);
  }
}

GeneralisationCase::~GeneralisationCase() = default;
GeneralisationCase::GeneralisationCase(GeneralisationCase&&) noexcept = default;
GeneralisationCase& GeneralisationCase::operator=(GeneralisationCase&&) noexcept = default;

std::string GeneralisationCase::name() const {
  char noise[32];
  std::snprintf(noise, sizeof noise, "%g%%", 100.0 * config_.noise_fraction);
  return to_string(config_.field) + "/" + to_string(config_.texture) + "/" + noise;
}

double GeneralisationCase::texture_level(Vec2 X_px) const {
  if (texture_->speckle) return texture_->speckle->level(X_px);
  return 0.2 + 0.6 * texture_->fingerprint->ridge(X_px);
}

double GeneralisationCase::chirp_wavelength_px(double X_px) const {
  const double span = config_.width_px - 1.0;
  const double ratio = config_.chirp_min_wavelength_px / config_.chirp_max_wavelength_px;
  return config_.chirp_max_wavelength_px * std::pow(ratio, X_px / span);
}

double GeneralisationCase::chirp_phase_rad(double X_px) const {
  // phi' = 2 pi / lambda(X) with lambda = lambda_max r^(X / span): phi = 2 pi span (r^(-X/span) - 1) /
  // (lambda_max ln(1 / r)).
  const double span = config_.width_px - 1.0;
  const double ratio = config_.chirp_min_wavelength_px / config_.chirp_max_wavelength_px;
  const double log_inv = -std::log(ratio);
  return kTwoPi * span * (std::pow(ratio, -X_px / span) - 1.0) / (config_.chirp_max_wavelength_px * log_inv);
}

FieldValue GeneralisationCase::field(Vec2 X, int frame) const {
  if (frame <= 0) return {};
  const int last = frames_ - 1;
  const double progress = static_cast<double>(frame) / last;  // 1 at the last frame
  const Vec2 c = centre_of(config_);
  switch (config_.field) {
    case GeneralisationField::kSubpixelShift: {
      const auto k = static_cast<std::size_t>(frame - 1);
      const double angle = kSubpixelAngleDeg[k] * kDegToRad;
      return translation({kSubpixelShiftPx[k] * std::cos(angle), kSubpixelShiftPx[k] * std::sin(angle)});
    }
    case GeneralisationField::kIntegerShift:
      return translation(kIntegerShiftPx[static_cast<std::size_t>(frame)]);
    case GeneralisationField::kChirp: {
      const double phase = chirp_phase_rad(X.x);
      const double a = config_.chirp_amplitude_px;
      FieldValue v;
      v.displacement_px = {a * std::sin(phase), 0.0};
      v.gradient.xx = a * std::cos(phase) * kTwoPi / chirp_wavelength_px(X.x);
      return v;
    }
    case GeneralisationField::kStep: {
      const double span = config_.width_px - 1.0;
      const double log_ratio = std::log(kStepNarrowestPx / kStepWidestPx);
      const double width = kStepWidestPx * std::exp(log_ratio * X.x / span);
      const double half = 0.5 * kStepAmplitudePx * progress;
      const double t = (X.y - c.y) / width;
      const double th = std::tanh(t), sech2 = 1.0 - th * th;
      FieldValue v;
      v.displacement_px = {half * th, 0.0};
      v.gradient.xy = half * sech2 / width;
      v.gradient.xx = -half * sech2 * t * log_ratio / span;  // through dw/dX = w log_ratio / span
      return v;
    }
    case GeneralisationField::kStretch:
      return linear({kStretchFinal * progress, 0.0, 0.0, 0.0}, X, c);
    case GeneralisationField::kRotation: {
      const double angle = kRotationFinalDeg * kDegToRad * progress;
      const double co = std::cos(angle), si = std::sin(angle);
      return linear({co - 1.0, -si, si, co - 1.0}, X, c);
    }
    case GeneralisationField::kCreep: {
      // Steps growing linearly from the first to the last: a_k = sum_{j<=k} d_j.
      const double k = frame;
      const double slope = last > 1 ? (kCreepLastStepPx - kCreepFirstStepPx) / (last - 1) : 0.0;
      const double amplitude = kCreepFirstStepPx * k + slope * k * (k - 1.0) / 2.0;
      const double sigma = 0.25 * config_.height_px;
      const double dx = X.x - c.x, dy = X.y - c.y;
      const double g = std::exp(-(dx * dx + dy * dy) / (2.0 * sigma * sigma));
      const double ex = std::cos(kCreepDirectionDeg * kDegToRad),
                   ey = std::sin(kCreepDirectionDeg * kDegToRad);
      const double gx = -g * dx / (sigma * sigma), gy = -g * dy / (sigma * sigma);
      FieldValue v;
      v.displacement_px = {amplitude * g * ex, amplitude * g * ey};
      v.gradient = {amplitude * ex * gx, amplitude * ex * gy, amplitude * ey * gx, amplitude * ey * gy};
      return v;
    }
  }
  return {};
}

FrameField::Inverse GeneralisationCase::invert(Vec2 x_px, int frame, Vec2 guess_px) const {
  Vec2 X = guess_px;
  double residual = 0.0;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const FieldValue v = field(X, frame);
    const double rx = X.x + v.displacement_px.x - x_px.x, ry = X.y + v.displacement_px.y - x_px.y;
    residual = std::hypot(rx, ry);
    if (residual < 1e-10) break;
    // F dX = r with F = I + H.
    const double a = 1.0 + v.gradient.xx, b = v.gradient.xy, c = v.gradient.yx, d = 1.0 + v.gradient.yy;
    const double det = a * d - b * c;
    X.x -= (d * rx - b * ry) / det;
    X.y -= (a * ry - c * rx) / det;
  }
  return {X, residual};
}

cv::Mat GeneralisationCase::render_clean(int frame, double* max_residual_px) const {
  cv::Mat out(height(), width(), CV_32F);
  std::vector<double> row_residual(static_cast<std::size_t>(height()), 0.0);
  cv::parallel_for_(cv::Range(0, height()), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* row = out.ptr<float>(y);
      double worst = 0.0;
      Vec2 previous;
      for (int x = 0; x < width(); ++x) {
        const Vec2 p{double(x), double(y)};
        // The first pixel starts from one fixed-point step, the others from the left neighbour's solution
        // moved by one pixel: the field changes little over a pixel.
        Vec2 guess{previous.x + 1.0, previous.y};
        if (x == 0) {
          const Vec2 u = field(p, frame).displacement_px;
          guess = {p.x - u.x, p.y - u.y};
        }
        const FrameField::Inverse inv = invert(p, frame, guess);
        previous = inv.reference_px;
        worst = std::max(worst, inv.residual_px);
        row[x] = static_cast<float>(texture_level(inv.reference_px));
      }
      row_residual[static_cast<std::size_t>(y)] = worst;
    }
  });
  if (max_residual_px) *max_residual_px = *std::max_element(row_residual.begin(), row_residual.end());
  return out;
}

cv::Mat GeneralisationCase::add_noise(const cv::Mat& clean, int frame) const {
  std::mt19937_64 rng(mix_seed(config_.seed, 0x4E015E00ULL + static_cast<std::uint64_t>(frame)));
  // std::normal_distribution needs a positive sigma; noise-free frames are only quantised.
  std::normal_distribution<double> normal(0.0, std::max(config_.noise_fraction, 1e-300));
  const bool noisy = config_.noise_fraction > 0.0;
  cv::Mat out(clean.size(), CV_16U);
  for (int y = 0; y < clean.rows; ++y) {
    const float* in = clean.ptr<float>(y);
    std::uint16_t* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < clean.cols; ++x) {
      const double value = std::clamp((in[x] + (noisy ? normal(rng) : 0.0)) * 65535.0, 0.0, 65535.0);
      o[x] = static_cast<std::uint16_t>(std::lround(value));
    }
  }
  return out;
}

}  // namespace tirstrain::samples
