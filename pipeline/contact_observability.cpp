#include "pipeline/contact_observability.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "contact/ellipse.hpp"
#include "core/error.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr int kModes = 5;  // radial modes 0..5: scale, shift, ellipse, three irregularity modes
constexpr int kUnknowns = 2 * kModes + 1;  // a0, a1, b1, ..., a5, b5
constexpr int kBoundarySamples = 720;
// Half a degree: the modes (up to 5 cycles round) turn by under 2.5 degrees of phase within a bin, and the
// bounds equal those from every pixel to 1e-4 px on the shipped tiny contact.
constexpr int kDirectionBins = 720;
using Vector = Eigen::Matrix<double, kUnknowns, 1>;
using Matrix = Eigen::Matrix<double, kUnknowns, kUnknowns>;

Vector modes_at(double phi) {
  Vector v;
  v(0) = 1.0;
  for (int k = 1; k <= kModes; ++k) {
    v(2 * k - 1) = std::cos(k * phi);
    v(2 * k) = std::sin(k * phi);
  }
  return v;
}

// The truth's border as a radius along each direction from the contact's centre (the generator's border is
// star-shaped about it).
struct PolarBorder {
  Vec2 centre;
  double reach_px;
  const samples::Trial* trial;
  double radius(double phi) const {
    double inside = 0.0, outside = reach_px;
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (inside + outside);
      const Vec2 p{centre.x + mid * std::cos(phi), centre.y + mid * std::sin(phi)};
      (trial->contact_signed_distance_px(p) <= 0.0 ? inside : outside) = mid;
    }
    return 0.5 * (inside + outside);
  }
};

// The pixels that bound the border, per direction bin: only the outermost pixel that shows a ridge inside
// and the innermost one that would show it outside can touch the feasible border there; the pixels behind
// them repeat a looser form of the same constraint and only slow the solver.
class BorderPixels {
 public:
  explicit BorderPixels(int bins) : inside_(static_cast<std::size_t>(bins)), outside_(inside_.size()) {}
  // `beyond_px`: how far past the truth's border the pixel lies along `phi` (< 0 inside).
  void add(double phi, double beyond_px, bool inside) {
    const double turns = phi / (2.0 * std::numbers::pi) + 0.5;
    const auto bin =
        std::min(inside_.size() - 1, static_cast<std::size_t>(std::max(0.0, turns) * inside_.size()));
    Pixel& kept = inside ? inside_[bin] : outside_[bin];
    if (!kept.used || (inside ? beyond_px > kept.beyond_px : beyond_px < kept.beyond_px))
      kept = {phi, beyond_px, true};
  }
  template <typename Visit>
  void for_each(Visit visit) const {
    for (const Pixel& p : inside_)
      if (p.used) visit(p.phi, p.beyond_px, true);
    for (const Pixel& p : outside_)
      if (p.used) visit(p.phi, p.beyond_px, false);
  }

 private:
  struct Pixel {
    double phi = 0.0, beyond_px = 0.0;
    bool used = false;
  };
  std::vector<Pixel> inside_, outside_;
};

// Linear constraints G x + h >= 0 on the mode amplitudes x.
struct Constraints {
  std::vector<Vector> rows;
  std::vector<double> offsets;
  void add(const Vector& g, double h) {
    rows.push_back(g);
    offsets.push_back(h);
  }
};

// max c.x subject to the constraints, from x = 0 (strictly feasible: the truth itself, with a small
// tolerance). Log-barrier Newton; the barrier weight grows until the duality gap is below ~1e-6.
Vector maximise(const Constraints& constraints, const Vector& c) {
  const auto m = static_cast<Eigen::Index>(constraints.rows.size());
  Eigen::Matrix<double, Eigen::Dynamic, kUnknowns> g(m, kUnknowns);
  Eigen::VectorXd h(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    g.row(i) = constraints.rows[static_cast<std::size_t>(i)].transpose();
    h(i) = constraints.offsets[static_cast<std::size_t>(i)];
  }
  Vector x = Vector::Zero();
  const auto barrier = [&](const Vector& z, double t) {
    const Eigen::VectorXd slack = g * z + h;
    if (slack.minCoeff() <= 0.0) return std::numeric_limits<double>::infinity();
    return -t * c.dot(z) - slack.array().log().sum();
  };
  for (double t = 1.0; static_cast<double>(m) / t > 1e-6; t *= 8.0) {
    for (int iteration = 0; iteration < 100; ++iteration) {
      const Eigen::VectorXd inverse_slack = (g * x + h).cwiseInverse();
      const Vector gradient = -t * c - g.transpose() * inverse_slack;
      const Matrix hessian = g.transpose() * inverse_slack.cwiseAbs2().asDiagonal() * g;
      const Vector step = hessian.ldlt().solve(-gradient);
      const double decrement = -gradient.dot(step);
      if (!(decrement > 1e-10)) break;
      const double start = barrier(x, t);
      double length = 1.0;
      while (barrier(x + length * step, t) > start - 0.25 * length * decrement && length > 1e-12)
        length *= 0.5;
      x += length * step;
    }
  }
  return x;
}

}  // namespace

std::optional<contact::Ellipse> truth_contact_ellipse(const cv::Mat& mask) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::vector<cv::Point2d> outline;
  // Where the contact runs off the frame, the mask's outline follows the frame's edge: those pixels are the
  // frame's, not the contact's, and would pull the fit towards the frame's centre.
  const auto on_frame_edge = [&](const cv::Point& p) {
    return p.x == 0 || p.y == 0 || p.x == mask.cols - 1 || p.y == mask.rows - 1;
  };
  for (const auto& contour : contours)
    for (const auto& p : contour)
      if (!on_frame_edge(p)) outline.emplace_back(p.x, p.y);
  std::optional<contact::Ellipse> ellipse = contact::fit_ellipse_direct(outline);
  if (ellipse) {
    ellipse->semi_major_px += 0.5;
    ellipse->semi_minor_px += 0.5;
  }
  return ellipse;
}

namespace {

constexpr double kTolerance_px = 0.02;  // keeps the truth strictly feasible for pixels on its border

// Alternatives to the truth: its border plus the modes. Their truth ellipse is the direct fit of the border,
// as for the truth itself; its centre is linear in small mode amplitudes (Jacobian by central differences).
class AlternativeBorders {
 public:
  AlternativeBorders(Vec2 centre, const PolarBorder& border)
      : centre_(centre), phis_(kBoundarySamples), radii_(kBoundarySamples) {
    for (std::size_t i = 0; i < phis_.size(); ++i) {
      phis_[i] = 2.0 * std::numbers::pi * static_cast<double>(i) / kBoundarySamples;
      radii_[i] = border.radius(phis_[i]);
    }
  }
  Eigen::Vector2d ellipse_centre(const Vector& modes) const {
    std::vector<cv::Point2d> points;
    points.reserve(phis_.size());
    for (std::size_t i = 0; i < phis_.size(); ++i) {
      const double r = radii_[i] + modes_at(phis_[i]).dot(modes);
      points.emplace_back(centre_.x + r * std::cos(phis_[i]), centre_.y + r * std::sin(phis_[i]));
    }
    const std::optional<contact::Ellipse> e = contact::fit_ellipse_direct(points);
    if (!e) throw Error("contact observability: the truth's border does not fit an ellipse");
    return Eigen::Vector2d(e->cx_px, e->cy_px);
  }
  Eigen::Matrix<double, 2, kUnknowns> jacobian() const {
    Eigen::Matrix<double, 2, kUnknowns> j;
    for (int k = 0; k < kUnknowns; ++k) {
      Vector d = Vector::Zero();
      d(k) = 0.01;
      j.col(k) = (ellipse_centre(d) - ellipse_centre(-d)) / 0.02;
    }
    return j;
  }

 private:
  Vec2 centre_;
  std::vector<double> phis_, radii_;
};

// Pixel noise at the background level: shot noise, read noise and the quantisation step.
double background_noise_sigma(const samples::Trial& trial) {
  const samples::SynthConfig& config = trial.config();
  const samples::SensorConfig& sensor = config.sensor;
  const double level = std::clamp(sensor.gain * trial.background_level(), 0.0, 1.0);
  const double full_scale = config.image.bit_depth == 16 ? 65535.0 : 255.0;
  const double shot = sensor.full_well_electrons > 0.0 ? level / sensor.full_well_electrons : 0.0;
  return std::sqrt(shot + sensor.read_noise * sensor.read_noise + 1.0 / (12.0 * full_scale * full_scale));
}

// A pixel constrains the border when its ridge shows: inside, with the contrast it has there; outside, with
// the contrast it would have right at the border (the fade's floor, a full edge weight). Counts the pixels
// in `bound`.
void add_pixel_constraints(const samples::Trial& trial, int frame, const PolarBorder& border,
                           double threshold, const ObservabilityOptions& options, CentreBound& bound,
                           Constraints& constraints) {
  const double ridge_contrast =
      std::abs(trial.config().fingerprint.ridge_contrast) * trial.config().sensor.gain;
  const Vec2 centre = border.centre;
  BorderPixels pixels(kDirectionBins);
  const samples::FrameField field = trial.field(frame);
  for (int y = 0; y < trial.height(); ++y)
    for (int x = 0; x < trial.width(); ++x) {
      const Vec2 p{double(x), double(y)};
      const double s = trial.contact_signed_distance_px(p);
      if (std::abs(s) > options.band_px) continue;
      const double ridge = trial.fingerprint().ridge(field.invert(p).reference_px);
      const double relative = s <= 0.0 ? trial.edge_weight(s) * trial.border_fade(s) : trial.border_fade(0.0);
      if (ridge_contrast * relative * ridge <= threshold) {
        ++bound.hidden_pixels;
        continue;
      }
      const double phi = std::atan2(p.y - centre.y, p.x - centre.x);
      pixels.add(phi, std::hypot(p.x - centre.x, p.y - centre.y) - border.radius(phi), s <= 0.0);
      ++(s <= 0.0 ? bound.inside_pixels : bound.outside_pixels);
    }
  pixels.for_each([&](double phi, double beyond_px, bool inside) {
    if (inside)  // r_pixel <= r_border + modes
      constraints.add(modes_at(phi), kTolerance_px - beyond_px);
    else  // r_pixel > r_border + modes
      constraints.add(-modes_at(phi), kTolerance_px + beyond_px);
  });
}

// Alternatives stay within the band that was looked at (an unconstrained side would run away otherwise), and
// the irregularity modes within `mode_bound` times the generator's prior.
void add_mode_bounds(const samples::Trial& trial, const ObservabilityOptions& options,
                     Constraints& constraints) {
  const auto add_bound = [&](int j, double limit) {
    for (double sign : {1.0, -1.0}) {
      Vector g = Vector::Zero();
      g(j) = -sign;
      constraints.add(g, limit);
    }
  };
  for (int j = 0; j < kUnknowns; ++j) add_bound(j, options.band_px);
  const Vec2 axes = trial.history().contact_semi_axes_px();
  const double mean_radius_px = std::sqrt(axes.x * axes.y);
  for (int k = 3; k <= kModes; ++k) {
    const double limit = options.mode_bound * trial.config().contact.border_irregularity * mean_radius_px /
                         (1.0 + 0.5 * (k - 2));
    for (int j : {2 * k - 1, 2 * k}) add_bound(j, limit + kTolerance_px);
  }
}

}  // namespace

CentreBound contact_centre_bound(const samples::Trial& trial, int frame,
                                 const ObservabilityOptions& options) {
  const Vec2 centre = trial.history().contact_centre_px();
  const Vec2 axes = trial.history().contact_semi_axes_px();
  const PolarBorder border{centre, 3.0 * std::max(axes.x, axes.y) + 10.0, &trial};
  const AlternativeBorders alternatives(centre, border);
  const Eigen::Vector2d centre_0 = alternatives.ellipse_centre(Vector::Zero());
  const Eigen::Matrix<double, 2, kUnknowns> jacobian = alternatives.jacobian();

  CentreBound bound;
  bound.noise_sigma = background_noise_sigma(trial);
  Constraints constraints;
  add_pixel_constraints(trial, frame, border, options.k_sigma * bound.noise_sigma, options, bound,
                        constraints);
  if (bound.inside_pixels == 0)
    throw Error("contact observability: frame " + std::to_string(frame) + " shows no ridge in contact");
  add_mode_bounds(trial, options, constraints);

  // The widest range of the centre along any of the directions.
  for (int d = 0; d < options.directions; ++d) {
    const double angle = std::numbers::pi * d / options.directions;
    const Eigen::Vector2d u(std::cos(angle), std::sin(angle));
    const Vector along = jacobian.transpose() * u;
    const double high = (alternatives.ellipse_centre(maximise(constraints, along)) - centre_0).dot(u);
    const double low = (alternatives.ellipse_centre(maximise(constraints, -along)) - centre_0).dot(u);
    if (0.5 * (high - low) > bound.half_range_px) {
      bound.half_range_px = 0.5 * (high - low);
      bound.direction_deg = angle * 180.0 / std::numbers::pi;
    }
  }
  return bound;
}

}  // namespace tirstrain::pipeline
