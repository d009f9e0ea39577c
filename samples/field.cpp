#include "samples/field.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.hpp"

namespace tirstrain::samples {
namespace {

Gradient2 times(const Gradient2& h, const Mat2& m) {
  return {h.xx * m.a + h.xy * m.c, h.xx * m.b + h.xy * m.d, h.yx * m.a + h.yy * m.c, h.yx * m.b + h.yy * m.d};
}

// Maps a model InvalidParameter to the scene key the user wrote.
std::string scene_key_of(const std::string& parameter) {
  if (parameter == "normal_N") return "synthesis.contact.normal_N";
  if (parameter == "radius_m") return "synthesis.contact.radius_m";
  if (parameter == "friction") return "synthesis.loading.friction";
  if (parameter == "young_Pa") return "tissue.E_Pa";
  if (parameter == "poisson") return "tissue.nu";
  return "synthesis.loading";
}

}  // namespace

FrameField FrameField::affine(Vec2 centre_px, const Gradient2& h, Vec2 translation_px) {
  FrameField f;
  f.kind_ = Kind::kAffine;
  f.centre_px_ = centre_px;
  f.h_ = h;
  f.translation_px_ = translation_px;
  return f;
}

FrameField FrameField::contact(const model::CattaneoMindlin& model, Vec2 centre_px, double px_per_m,
                               std::optional<Mat2> ellipse_map) {
  FrameField f;
  f.kind_ = Kind::kContact;
  f.centre_px_ = centre_px;
  f.model_.emplace(model);
  f.px_per_m_ = px_per_m;
  f.map_ = ellipse_map;
  return f;
}

Vec2 FrameField::model_point_m(Vec2 X) const {
  const double dx = (X.x - centre_px_.x) / px_per_m_;
  const double dy = (X.y - centre_px_.y) / px_per_m_;
  if (!map_) return {dx, dy};
  return {map_->a * dx + map_->b * dy, map_->c * dx + map_->d * dy};
}

FieldValue FrameField::evaluate(Vec2 X) const {
  switch (kind_) {
    case Kind::kIdentity:
      return {};
    case Kind::kAffine: {
      const double dx = X.x - centre_px_.x;
      const double dy = X.y - centre_px_.y;
      return {{h_.xx * dx + h_.xy * dy + translation_px_.x, h_.yx * dx + h_.yy * dy + translation_px_.y}, h_};
    }
    case Kind::kContact: {
      const Vec2 p = model_point_m(X);
      const model::FieldSample s = model_->evaluate(p.x, p.y);
      FieldValue v{{s.displacement_m.x * px_per_m_, s.displacement_m.y * px_per_m_}, s.gradient};
      // Chain rule through the ellipse map; skipped for a circle so the truth strain is bit-identical to
      // the model's.
      if (map_) v.gradient = times(s.gradient, *map_);
      return v;
    }
  }
  return {};
}

Vec2 FrameField::displacement_px(Vec2 X) const {
  if (kind_ == Kind::kContact) {
    const Vec2 p = model_point_m(X);
    const Vec2 u = model_->displacement_m(p.x, p.y);
    return {u.x * px_per_m_, u.y * px_per_m_};
  }
  return evaluate(X).displacement_px;
}

FrameField::Inverse FrameField::invert(Vec2 x) const {
  if (kind_ == Kind::kIdentity) return {x, 0.0};
  // The field is smooth and |H| << 1 almost everywhere, so x - u(x) is already within a small fraction of
  // a pixel and Newton converges in two or three steps. The gradient is only continuous (not differentiable)
  // on the circles r = c and r = a, which slows convergence there to superlinear but does not stop it.
  const Vec2 u0 = displacement_px(x);
  return invert(x, {x.x - u0.x, x.y - u0.y});
}

FrameField::Inverse FrameField::invert(Vec2 x, Vec2 guess) const {
  if (kind_ == Kind::kIdentity) return {x, 0.0};
  Vec2 X = guess;
  double residual = 0.0;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const FieldValue v = evaluate(X);
    const double rx = X.x + v.displacement_px.x - x.x;
    const double ry = X.y + v.displacement_px.y - x.y;
    residual = std::hypot(rx, ry);
    if (residual <= 1e-10) break;
    const double jxx = 1.0 + v.gradient.xx, jxy = v.gradient.xy, jyx = v.gradient.yx,
                 jyy = 1.0 + v.gradient.yy;
    const double det = jxx * jyy - jxy * jyx;
    // A fold (det <= 0) is outside what the scene validation allows; damped fixed-point steps still make
    // progress.
    if (!(det > 1e-6)) {
      X.x -= 0.5 * rx;
      X.y -= 0.5 * ry;
      continue;
    }
    X.x -= (jyy * rx - jxy * ry) / det;
    X.y -= (-jyx * rx + jxx * ry) / det;
  }
  if (residual > 1e-10) {
    const Vec2 u = displacement_px(X);
    residual = std::hypot(X.x + u.x - x.x, X.y + u.y - x.y);
  }
  return {X, residual};
}

LoadHistory::LoadHistory(const SynthConfig& config)
    : contact_(config.contact),
      loading_(config.loading),
      young_Pa_(config.scene.tissue.young_Pa),
      poisson_(config.scene.tissue.poisson),
      frames_(config.timing.frames),
      px_per_m_(config.scene.px_per_mm * 1000.0),
      direction_rad_(config.loading.direction_deg * std::numbers::pi / 180.0),
      last_frame_s_((config.timing.frames - 1) / config.timing.frame_rate_hz) {
  const double w = config.image.width_px, h = config.image.height_px;
  centre_px_ = {0.5 * (w - 1), 0.5 * (h - 1)};
  if (config.scene.reference_pattern_roi) {
    // Centre the contact in what the pattern band leaves free when the band runs along one edge (the full
    // width along the top or bottom, the full height along the left or right).
    const RoiPx& r = *config.scene.reference_pattern_roi;
    const bool full_width = r.x == 0 && r.width == static_cast<int>(w);
    const bool full_height = r.y == 0 && r.height == static_cast<int>(h);
    if (full_width && r.y == 0 && r.height < h)
      centre_px_.y = 0.5 * (r.height + h - 1);
    else if (full_width && r.y + r.height == static_cast<int>(h) && r.y > 0)
      centre_px_.y = 0.5 * (r.y - 1);
    else if (full_height && r.x == 0 && r.width < w)
      centre_px_.x = 0.5 * (r.width + w - 1);
    else if (full_height && r.x + r.width == static_cast<int>(w) && r.x > 0)
      centre_px_.x = 0.5 * (r.x - 1);
  }
  if (contact_.centre_px) centre_px_ = *contact_.centre_px;

  try {
    model::CattaneoMindlinParams p;
    p.normal_N = contact_.normal_N;
    p.young_Pa = young_Pa_;
    p.poisson = poisson_;
    p.friction = loading_.friction;
    p.direction_rad = direction_rad_;
    if (contact_.shape == ContactShape::kHertz) {
      p.radius_m = contact_.radius_m;
      equivalent_radius_m_ = contact_.radius_m;
    } else {
      // An elliptical contact reuses the circular field through scaled coordinates: the sphere radius is
      // chosen so that the Hertz radius equals the ellipse's geometric-mean semi-axis.
      const double ax_m = contact_.semi_axes_mm[0] * 1e-3, ay_m = contact_.semi_axes_mm[1] * 1e-3;
      const double a_eq = std::sqrt(ax_m * ay_m);
      const double e_star = young_Pa_ / (1.0 - poisson_ * poisson_);
      equivalent_radius_m_ = 4.0 * e_star * a_eq * a_eq * a_eq / (3.0 * contact_.normal_N);
      p.radius_m = equivalent_radius_m_;
    }
    p.tangential_N = loading_.friction * contact_.normal_N;
    const model::CattaneoMindlin full_slip(p);
    contact_radius_m_ = full_slip.hertz().contact_radius_m;
    max_shift_m_ = full_slip.rigid_shift_m();
  } catch (const model::InvalidParameter& e) {
    throw Error(std::string("the contact model rejects this value: ") + e.what(),
                {.file = config.scene.file, .key = scene_key_of(e.parameter())});
  }

  if (contact_.shape == ContactShape::kHertz) {
    semi_axes_px_ = {contact_radius_m_ * px_per_m_, contact_radius_m_ * px_per_m_};
  } else {
    semi_axes_px_ = {contact_.semi_axes_mm[0] * 1e-3 * px_per_m_,
                     contact_.semi_axes_mm[1] * 1e-3 * px_per_m_};
    contact_angle_rad_ = contact_.angle_deg * std::numbers::pi / 180.0;
    const double cs = std::cos(contact_angle_rad_), sn = std::sin(contact_angle_rad_);
    const double sx = contact_radius_m_ / (contact_.semi_axes_mm[0] * 1e-3);
    const double sy = contact_radius_m_ / (contact_.semi_axes_mm[1] * 1e-3);
    // M = Rot(angle) diag(sx, sy) Rot(-angle).
    ellipse_map_ = Mat2{cs * cs * sx + sn * sn * sy, cs * sn * (sx - sy), cs * sn * (sx - sy),
                        sn * sn * sx + cs * cs * sy};
  }
}

LoadState LoadHistory::at(double t_s) const {
  LoadState s;
  s.t_s = t_s;
  s.normal_N = contact_.normal_N;
  const double since_start_s = std::max(0.0, t_s - loading_.shear_start_s);
  const double ramp_span_s = last_frame_s_ - loading_.shear_start_s;
  s.ramp =
      ramp_span_s > 0.0 ? std::clamp(since_start_s / ramp_span_s, 0.0, 1.0) : (since_start_s > 0 ? 1.0 : 0.0);
  // Snap the loading direction's components so axis-aligned directions give exact zeros (no "-0" or 1e-16
  // plate motion across the axis).
  const auto snap = [](double v) { return std::abs(v) < 1e-14 ? 0.0 : v; };
  const double cs = snap(std::cos(direction_rad_)), sn = snap(std::sin(direction_rad_));
  switch (loading_.field) {
    case FieldKind::kCattaneoMindlin: {
      const double plate_m = loading_.plate_speed_mm_s * 1e-3 * since_start_s;
      const double mu_p = loading_.friction * contact_.normal_N;
      s.plate_px = {plate_m * px_per_m_ * cs + 0.0, plate_m * px_per_m_ * sn + 0.0};
      if (plate_m >= max_shift_m_) {
        s.full_slip = true;
        s.tangential_N = mu_p;
        s.rigid_shift_m = max_shift_m_;
        s.stick_radius_m = 0.0;
      } else {
        s.tangential_N = mu_p * (1.0 - std::pow(1.0 - plate_m / max_shift_m_, 1.5));
        s.rigid_shift_m = plate_m;  // refined from the model in field_at (identical up to rounding)
        s.stick_radius_m = contact_radius_m_ * std::cbrt(1.0 - s.tangential_N / mu_p);
      }
      break;
    }
    case FieldKind::kRigid:
    case FieldKind::kAffine:
      s.plate_px = {s.ramp * loading_.translation_px.x, s.ramp * loading_.translation_px.y};
      break;
    case FieldKind::kNone:
      break;
  }
  return s;
}

FrameField LoadHistory::field_at(const LoadState& s) const {
  switch (loading_.field) {
    case FieldKind::kCattaneoMindlin: {
      if (s.tangential_N <= 0.0) return FrameField();
      model::CattaneoMindlinParams p;
      p.normal_N = contact_.normal_N;
      p.tangential_N = std::min(s.tangential_N, loading_.friction * contact_.normal_N);
      p.radius_m = equivalent_radius_m_;
      p.young_Pa = young_Pa_;
      p.poisson = poisson_;
      p.friction = loading_.friction;
      p.direction_rad = direction_rad_;
      return FrameField::contact(model::CattaneoMindlin(p), centre_px_, px_per_m_, ellipse_map_);
    }
    case FieldKind::kRigid: {
      const double angle = s.ramp * loading_.rotation_deg * std::numbers::pi / 180.0;
      const double c = std::cos(angle), n = std::sin(angle);
      return FrameField::affine(centre_px_, {c - 1.0, -n, n, c - 1.0},
                                {s.ramp * loading_.translation_px.x, s.ramp * loading_.translation_px.y});
    }
    case FieldKind::kAffine: {
      const Gradient2& h = loading_.gradient;
      return FrameField::affine(centre_px_, {s.ramp * h.xx, s.ramp * h.xy, s.ramp * h.yx, s.ramp * h.yy},
                                {s.ramp * loading_.translation_px.x, s.ramp * loading_.translation_px.y});
    }
    case FieldKind::kNone:
      break;
  }
  return FrameField();
}

}  // namespace tirstrain::samples
