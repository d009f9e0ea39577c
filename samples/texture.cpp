#include "samples/texture.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "core/smoothstep.hpp"

namespace tirstrain::samples {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Quintic smoothstep: C2, so the minutia window adds no visible kink to the ridge flow.
double unit(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

}  // namespace

std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b) {
  return splitmix64(a ^ splitmix64(b));
}

Fingerprint::Fingerprint(const FingerprintConfig& config, double px_per_mm, double period_mm, Vec2 core_px,
                         Vec2 extent_px, std::uint64_t seed)
    : wavenumber_(kTwoPi / (period_mm * px_per_mm)),
      period_px_(period_mm * px_per_mm),
      core_px_(core_px),
      axis_cos_(std::cos(config.axis_deg * std::numbers::pi / 180.0)),
      axis_sin_(std::sin(config.axis_deg * std::numbers::pi / 180.0)),
      loop_length_px_(config.loop_length_mm * px_per_mm),
      core_smoothing_px_(0.25 * period_mm * px_per_mm),
      softmin_px_(0.5 * period_mm * px_per_mm),
      minutia_core_px_(0.25 * period_mm * px_per_mm),
      pore_depth_(config.pore_depth),
      pores_(PatternConfig{config.pore_spacing_mm, config.pore_sigma_mm, 1.0, 0.6}, px_per_mm,
             mix_seed(seed, 0x9025ULL)) {
  std::mt19937_64 rng(mix_seed(seed, 0xF1A6E5ULL));
  std::uniform_real_distribution<double> u01(0.0, 1.0);

  if (config.delta_offset_mm) {
    // The triradius forms at the saddle between the two centres, so the second centre sits twice as far.
    has_delta_ = true;
    const double dx = 2.0 * config.delta_offset_mm->x * px_per_mm,
                 dy = 2.0 * config.delta_offset_mm->y * px_per_mm;
    second_centre_local_ = {dx * axis_cos_ + dy * axis_sin_, -dx * axis_sin_ + dy * axis_cos_};
  }

  // Long-wavelength warps (4-8 mm) bend the flow gently; amplitude half a period per unit flow_warp keeps
  // the local ridge period within about +-10 % (a real finger's period is nearly uniform).
  for (int i = 0; i < 4; ++i) {
    const double wavelength_px = (4.0 + 4.0 * u01(rng)) * px_per_mm;
    const double angle = kTwoPi * u01(rng);
    const double k = kTwoPi / wavelength_px;
    warp_wavevector_[i] = {k * std::cos(angle), k * std::sin(angle)};
    warp_phase_[i] = kTwoPi * u01(rng);
    warp_amplitude_px_[i] = config.flow_warp * 0.5 * period_px_ * (0.6 + 0.4 * u01(rng));
  }

  // Minutia pairs over the image plus a margin for material that moves into view.
  const double max_outer_px = (1.1 + 1.5 + 3.0) * period_px_;
  const double margin_px = max_outer_px + 0.25 * std::max(extent_px.x, extent_px.y);
  const double span_x = extent_px.x + 2 * margin_px, span_y = extent_px.y + 2 * margin_px;
  const double area_mm2 = span_x * span_y / (px_per_mm * px_per_mm);
  const auto count = static_cast<std::size_t>(std::llround(0.5 * config.minutiae_per_mm2 * area_mm2));
  pairs_.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    Pair p;
    p.mid = {-margin_px + span_x * u01(rng), -margin_px + span_y * u01(rng)};
    const double separation = (0.8 + 1.4 * u01(rng)) * period_px_;
    const double angle = kTwoPi * u01(rng);
    const Vec2 half{0.5 * separation * std::cos(angle), 0.5 * separation * std::sin(angle)};
    p.a = {p.mid.x - half.x, p.mid.y - half.y};
    p.b = {p.mid.x + half.x, p.mid.y + half.y};
    p.sign = u01(rng) < 0.5 ? -1.0 : 1.0;
    p.inner_px = 0.5 * separation + 1.5 * period_px_;
    p.outer_px = p.inner_px + 3.0 * period_px_;
    pairs_.push_back(p);
  }
  bin_origin_px_ = {-margin_px, -margin_px};
  bin_size_px_ = 4.0 * period_px_;
  bins_x_ = static_cast<int>(std::ceil(span_x / bin_size_px_));
  bins_y_ = static_cast<int>(std::ceil(span_y / bin_size_px_));
  bins_.assign(static_cast<std::size_t>(bins_x_) * bins_y_, {});
  for (std::size_t i = 0; i < pairs_.size(); ++i) {
    const Pair& p = pairs_[i];
    const int x0 =
        std::max(0, static_cast<int>(std::floor((p.mid.x - p.outer_px - bin_origin_px_.x) / bin_size_px_)));
    const int x1 = std::min(
        bins_x_ - 1, static_cast<int>(std::floor((p.mid.x + p.outer_px - bin_origin_px_.x) / bin_size_px_)));
    const int y0 =
        std::max(0, static_cast<int>(std::floor((p.mid.y - p.outer_px - bin_origin_px_.y) / bin_size_px_)));
    const int y1 = std::min(
        bins_y_ - 1, static_cast<int>(std::floor((p.mid.y + p.outer_px - bin_origin_px_.y) / bin_size_px_)));
    for (int by = y0; by <= y1; ++by)
      for (int bx = x0; bx <= x1; ++bx)
        bins_[static_cast<std::size_t>(by) * bins_x_ + bx].push_back(static_cast<int>(i));
  }
}

double Fingerprint::ridge(Vec2 X) const {
  double amplitude = 1.0;
  const double p = phase(X, amplitude);
  const double ridge = 0.5 + 0.5 * amplitude * std::cos(p);
  return pore_depth_ > 0.0 ? ridge * (1.0 - pore_depth_ * pores_.darkness(X)) : ridge;
}

Vec2 Fingerprint::phase_gradient(Vec2 X) const {
  constexpr double h = 1e-3;
  double amplitude = 1.0;
  const auto wrapped = [](double d) { return d - kTwoPi * std::round(d / kTwoPi); };
  const double dx = wrapped(phase({X.x + h, X.y}, amplitude) - phase({X.x - h, X.y}, amplitude));
  const double dy = wrapped(phase({X.x, X.y + h}, amplitude) - phase({X.x, X.y - h}, amplitude));
  return {dx / (2.0 * h), dy / (2.0 * h)};
}

double Fingerprint::ridge_orientation_rad(Vec2 X) const {
  const Vec2 g = phase_gradient(X);
  if (g.x == 0.0 && g.y == 0.0) return 0.0;
  // Along the ridge: (-g_y, g_x); its angle modulo pi.
  double angle = std::atan2(g.x, -g.y);
  if (angle < 0.0) angle += std::numbers::pi;
  if (angle >= std::numbers::pi) angle -= std::numbers::pi;
  return angle;
}

double Fingerprint::phase(Vec2 X, double& amplitude) const {
  double px = X.x - core_px_.x, py = X.y - core_px_.y;
  const double wx = warp_amplitude_px_[0] *
                        std::sin(warp_wavevector_[0].x * px + warp_wavevector_[0].y * py + warp_phase_[0]) +
                    warp_amplitude_px_[1] *
                        std::sin(warp_wavevector_[1].x * px + warp_wavevector_[1].y * py + warp_phase_[1]);
  const double wy = warp_amplitude_px_[2] *
                        std::sin(warp_wavevector_[2].x * px + warp_wavevector_[2].y * py + warp_phase_[2]) +
                    warp_amplitude_px_[3] *
                        std::sin(warp_wavevector_[3].x * px + warp_wavevector_[3].y * py + warp_phase_[3]);
  px += wx;
  py += wy;
  const double along = px * axis_cos_ + py * axis_sin_;
  const double across = -px * axis_sin_ + py * axis_cos_;
  // Distance to the loop's axis segment, smoothed at the core so the innermost ridge is round, not a cone.
  const double beyond = along - std::clamp(along, 0.0, loop_length_px_);
  const double r0 = core_smoothing_px_;
  double rho = std::sqrt(across * across + beyond * beyond + r0 * r0) - r0;
  if (has_delta_) {
    const double dx = along - second_centre_local_.x, dy = across - second_centre_local_.y;
    const double rho2 = std::sqrt(dx * dx + dy * dy + r0 * r0) - r0;
    rho = std::min(rho, rho2) - softmin_px_ * std::log1p(std::exp(-std::abs(rho - rho2) / softmin_px_));
  }
  double phase = wavenumber_ * rho;
  amplitude = 1.0;

  const int bx = static_cast<int>(std::floor((X.x - bin_origin_px_.x) / bin_size_px_));
  const int by = static_cast<int>(std::floor((X.y - bin_origin_px_.y) / bin_size_px_));
  if (bx >= 0 && by >= 0 && bx < bins_x_ && by < bins_y_) {
    const double inv_two_s2 = 1.0 / (2.0 * minutia_core_px_ * minutia_core_px_);
    for (int index : bins_[static_cast<std::size_t>(by) * bins_x_ + bx]) {
      const Pair& p = pairs_[static_cast<std::size_t>(index)];
      const double mx = X.x - p.mid.x, my = X.y - p.mid.y;
      const double r2 = mx * mx + my * my;
      if (r2 >= p.outer_px * p.outer_px) continue;
      const double ax = X.x - p.a.x, ay = X.y - p.a.y, bxx = X.x - p.b.x, byy = X.y - p.b.y;
      const double angle = std::atan2(ax * byy - ay * bxx, ax * bxx + ay * byy);
      const double r = std::sqrt(r2);
      const double window =
          r <= p.inner_px ? 1.0 : 1.0 - smoothstep5((r - p.inner_px) / (p.outer_px - p.inner_px));
      phase += p.sign * window * angle;
      const double da2 = ax * ax + ay * ay, db2 = bxx * bxx + byy * byy;
      if (da2 < 25.0 * minutia_core_px_ * minutia_core_px_) amplitude *= 1.0 - std::exp(-da2 * inv_two_s2);
      if (db2 < 25.0 * minutia_core_px_ * minutia_core_px_) amplitude *= 1.0 - std::exp(-db2 * inv_two_s2);
    }
  }
  return phase;
}

PlatePattern::PlatePattern(const PatternConfig& config, double px_per_mm, std::uint64_t seed)
    : spacing_px_(config.dot_spacing_mm * px_per_mm),
      inv_two_sigma2_(1.0 / (2.0 * std::pow(config.dot_sigma_mm * px_per_mm, 2))),
      fill_(config.fill),
      seed_(mix_seed(seed, 0x9A77E2ULL)) {}

double PlatePattern::darkness(Vec2 p) const {
  const double sigma_px = std::sqrt(0.5 / inv_two_sigma2_);
  const int reach = std::max(1, static_cast<int>(std::ceil(4.0 * sigma_px / spacing_px_)));
  const auto ci = static_cast<long long>(std::floor(p.x / spacing_px_));
  const auto cj = static_cast<long long>(std::floor(p.y / spacing_px_));
  double sum = 0.0;
  for (long long j = cj - reach; j <= cj + reach; ++j) {
    for (long long i = ci - reach; i <= ci + reach; ++i) {
      const std::uint64_t h =
          mix_seed(seed_, (static_cast<std::uint64_t>(i) << 32) ^ static_cast<std::uint64_t>(j));
      if (unit(h) >= fill_) continue;
      const std::uint64_t h2 = splitmix64(h);
      const double x = (static_cast<double>(i) + 0.15 + 0.7 * unit(h2)) * spacing_px_;
      const double y = (static_cast<double>(j) + 0.15 + 0.7 * unit(splitmix64(h2))) * spacing_px_;
      const double d2 = (p.x - x) * (p.x - x) + (p.y - y) * (p.y - y);
      sum += (0.7 + 0.6 * unit(splitmix64(h2 ^ 0x5A5A))) * std::exp(-d2 * inv_two_sigma2_);
    }
  }
  return 1.0 - std::exp(-1.5 * sum);
}

SweatBlobs::SweatBlobs(const SweatConfig& config, double px_per_mm, Vec2 centre_px, Vec2 semi_axes_px,
                       std::uint64_t seed)
    : depth_(config.depth) {
  std::mt19937_64 rng(mix_seed(seed, 0x5EA7ULL));
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int i = 0; i < config.blobs; ++i) {
    // Uniform over the contact ellipse (axis-aligned; blobs need not follow an elliptical contact's angle).
    const double r = std::sqrt(u01(rng)) * 0.85, angle = kTwoPi * u01(rng);
    const double radius_px =
        (config.radius_mm_min + (config.radius_mm_max - config.radius_mm_min) * u01(rng)) * px_per_mm;
    const double sigma_px = 0.5 * radius_px;
    blobs_.push_back({{centre_px.x + r * semi_axes_px.x * std::cos(angle),
                       centre_px.y + r * semi_axes_px.y * std::sin(angle)},
                      1.0 / (2.0 * sigma_px * sigma_px),
                      radius_px});
  }
}

double SweatBlobs::contrast_factor(Vec2 X) const {
  double factor = 1.0;
  for (const Blob& b : blobs_) {
    const double d2 = (X.x - b.centre.x) * (X.x - b.centre.x) + (X.y - b.centre.y) * (X.y - b.centre.y);
    if (d2 < 4.0 * b.radius_px * b.radius_px) factor *= 1.0 - depth_ * std::exp(-d2 * b.inv_two_sigma2);
  }
  return factor;
}

}  // namespace tirstrain::samples
