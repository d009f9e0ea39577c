#pragma once
// The displacement fields applied to the skin and the load history that drives them.
// Every field is a finite map x = X + u(X) from reference pixels X (the skin at frame 0) to image pixels x,
// with its exact gradient H = du/dX, so the renderer can invert it per pixel by Newton's method and the
// truth file can hold exactly what was applied.
#include <optional>

#include "core/tensor2.hpp"
#include "model/cattaneo_mindlin.hpp"
#include "samples/synth_config.hpp"

namespace tirstrain::samples {

struct FieldValue {
  Vec2 displacement_px;
  Gradient2 gradient;  // dimensionless, identical in pixel and metric units
};

// 2x2 matrix acting on column vectors, row-major.
struct Mat2 {
  double a = 1.0, b = 0.0, c = 0.0, d = 1.0;
};

// The field of one frame.
class FrameField {
 public:
  // u = 0.
  FrameField() = default;
  // u(X) = H (X - centre) + translation.
  static FrameField affine(Vec2 centre_px, const Gradient2& h, Vec2 translation_px);
  // Cattaneo–Mindlin field evaluated at metric coordinates X_m = M (X - centre) / px_per_m; u_px = px_per_m
  // u_m, H = H_cm M. M = identity for a Hertz (circular) contact; for an elliptical contact M maps the
  // ellipse onto the model's circle.
  static FrameField contact(const model::CattaneoMindlin& model, Vec2 centre_px, double px_per_m,
                            std::optional<Mat2> ellipse_map);

  FieldValue evaluate(Vec2 X_px) const;
  Vec2 displacement_px(Vec2 X_px) const;

  struct Inverse {
    Vec2 reference_px;
    double residual_px = 0.0;  // |X + u(X) - x| at the returned X
  };
  // Solves X + u(X) = x by Newton's method on the exact gradient, to about 1e-10 px.
  Inverse invert(Vec2 x_px) const;
  // The same from a starting guess (e.g. the neighbouring pixel's solution shifted by one pixel).
  Inverse invert(Vec2 x_px, Vec2 guess_px) const;

  bool is_identity() const { return kind_ == Kind::kIdentity; }
  const model::CattaneoMindlin* model() const { return model_ ? &*model_ : nullptr; }
  // Model coordinates (metres) of a reference pixel; meaningful only for a contact field.
  Vec2 model_point_m(Vec2 X_px) const;

 private:
  enum class Kind { kIdentity, kAffine, kContact };
  Kind kind_ = Kind::kIdentity;
  Vec2 centre_px_;
  Gradient2 h_;
  Vec2 translation_px_;
  std::optional<model::CattaneoMindlin> model_;
  double px_per_m_ = 1.0;
  std::optional<Mat2> map_;
};

// What happens at one instant of the trial.
struct LoadState {
  double t_s = 0.0;
  double normal_N = 0.0;
  double tangential_N = 0.0;    // Q along the loading direction (the model's, without fluctuation)
  double stick_radius_m = 0.0;  // c (0 in full slip and for non-contact fields)
  double rigid_shift_m = 0.0;   // delta_x of the stick zone along the loading direction
  double ramp = 0.0;            // 0 before the shear starts, 1 at the last frame (rigid/affine fields)
  bool full_slip = false;
  Vec2 plate_px;  // displacement of the glass plate (and its printed pattern), pixels
};

// The load history: P constant; displacement-controlled plate moving at plate_speed_mm_s from shear_start_s.
// While the plate displacement d is below the Mindlin limit delta_max (the stick zone follows the plate),
// Q = mu P [1 - (1 - d / delta_max)^(3/2)] (the exact inverse of the Mindlin compliance); beyond it full
// slip, Q = mu P, c = 0, and the skin field stays frozen while the plate keeps moving.
class LoadHistory {
 public:
  explicit LoadHistory(const SynthConfig& config);
  LoadState at(double t_s) const;
  FrameField field_at(const LoadState& state) const;

  Vec2 contact_centre_px() const { return centre_px_; }
  Vec2 contact_semi_axes_px() const { return semi_axes_px_; }
  double contact_angle_rad() const { return contact_angle_rad_; }
  double contact_radius_m() const { return contact_radius_m_; }  // a of the model (equivalent for an ellipse)
  double max_rigid_shift_m() const { return max_shift_m_; }
  double direction_rad() const { return direction_rad_; }
  double px_per_m() const { return px_per_m_; }
  double last_frame_s() const { return last_frame_s_; }

 private:
  ContactConfig contact_;
  LoadingConfig loading_;
  double young_Pa_ = 0.0;
  double poisson_ = 0.0;
  int frames_ = 0;
  double px_per_m_ = 0.0;
  double direction_rad_ = 0.0;
  Vec2 centre_px_;
  Vec2 semi_axes_px_;
  double contact_angle_rad_ = 0.0;
  double contact_radius_m_ = 0.0;
  double equivalent_radius_m_ = 0.0;  // sphere radius giving the contact radius (ellipse: sqrt(ax ay))
  double max_shift_m_ = 0.0;
  double last_frame_s_ = 0.0;
  std::optional<Mat2> ellipse_map_;
};

}  // namespace tirstrain::samples
