#pragma once
// Stick-zone radius c from the measured displacement field, by fitting the Cattaneo–Mindlin slip profile.
//
// Why not a displacement tolerance: just outside the stick zone the slip (skin displacement relative to the
// stuck core) grows only like (r − c)^(3/2) — the gradient is continuous and zero at r = c — so any fixed
// tolerance τ labels a ring of width ∝ τ^(2/3) outside c as stuck (0.5 px: c 21 % too large on the default
// scene, 0.2 px: 10 %). Instead the whole field is fitted:
//
//   d(X) = x − X = t + A_x·b_x(p; k) + A_y·b_y(p; k),   p = the reference point mapped onto the unit disk
//
// t is the stuck core's displacement (free, so a biased or missing plate estimate does not matter), b_x and
// b_y are the Cattaneo–Mindlin slip fields (u − δ) for tangential traction along x and y in units of
// μp0·a/(4G) (closed forms of docs/model.md; zero for |p| ≤ k), and k = c/a. For each k the four linear
// parameters come from least squares; k is the minimiser of the residual over [0, 1] (grid, then golden
// section). Any loading direction is a linear combination of b_x and b_y (the traction's radial profile is
// the same), so the direction needs no separate fit. An elliptical contact is mapped onto the disk by
// p = M (X − centre) / a with M = R(φ) diag(a/a_major, a/a_minor) R(−φ), a = sqrt(a_major a_minor), which is
// how samples/ builds its elliptical contacts; c is reported as k·a (the radius of the circle with the stick
// zone's area).
//
// Model selection and degenerate cases, all with defined values: a stick zone must lower the residual of the
// full-slip fit (k = 0) by `chi2_stick` noise variances, otherwise k = 0 (c = 0; a stick zone of a track
// spacing or two is not resolvable anyway). Slip must be detected — the fit lowers the residual of the
// no-slip fit (offset only) by `chi2_slip` noise variances, its largest predicted slip and the stuck core's
// shift both exceed `significance` × the residual RMS (and `min_slip_px`), and the core moved along the
// fitted traction direction (within 60°). Without detected slip, what the tracks say depends on the core:
// a core that has not moved means no tangential load, k = 1 (c = a; this assumes the reference frame precedes
// the load); a core that moved means a load whose slip annulus, if any, lies beyond the outermost track
// (Cattaneo–Mindlin slips at the rim first, as (ρ − c)^(3/2), so a thin annulus hides under the noise even
// inside the tracks' reach), so k is NaN (kSlipBeyondTracks): the tracks do not measure it. Reporting a there
// would claim no slip where the slip has only not been seen. Too few points give NaN (kTooFewPoints).
#include <cstdint>
#include <span>

#include "core/tensor2.hpp"

namespace tirstrain::strain {

// The contact in the reference image: p = to_disk · (X − centre_px) lies on the unit circle at its border.
struct ContactDisk {
  Vec2 centre_px;
  Gradient2 to_disk;       // 2×2 (xx, xy; yx, yy)
  double radius_px = 0.0;  // a = sqrt(semi-major · semi-minor)
};

// The disk map of an ellipse with semi-axes (major, minor) in pixels, major axis at `angle_rad` from +x.
ContactDisk contact_disk(Vec2 centre_px, double semi_major_px, double semi_minor_px, double angle_rad);

struct StickZoneOptions {
  double extent = 0.95;       // points used: |p| ≤ extent (the fading border band is left out); 0.95
  double significance = 4.0;  // slip is detected when the fitted slip exceeds this × the residual RMS; 4
  double min_slip_px = 0.02;  // ... and this many pixels; 0.02
  double chi2_slip = 25.0;    // ... and the fit lowers the residual by this × the noise variance; 25
  double chi2_stick = 16.0;   // a stick zone (k > 0) must lower the full-slip fit's residual this much; 16
  int min_points = 12;        // fewer points: no fit; default 12
  int grid = 24;              // k grid before the golden-section refinement; default 24
  // Throws Error naming the first value out of range.
  void check() const;
};

enum class StickZoneStatus : std::int8_t {
  kFit = 0,           // k from the fit (k = 0: full slip)
  kNoSlip = 1,        // no detectable slip: k = 1
  kTooFewPoints = 2,  // NaN
  // The core moved but no slip shows within the tracks: k is NaN (not measured).
  kSlipBeyondTracks = 3,
};

struct StickZoneFit {
  StickZoneStatus status = StickZoneStatus::kTooFewPoints;
  double ratio = 0.0;        // k = c/a (NaN when unknown)
  double radius_px = 0.0;    // c = k·a
  Vec2 shift_px;             // t: displacement of the stuck core
  Vec2 amplitude_px;         // (A_x, A_y): μp0·a/(4G)·(traction direction), pixels
  double max_slip_px = 0.0;  // largest fitted slip |A_x b_x + A_y b_y| over the points
  double residual_rms_px = 0.0;
  // Residual decrease of the fit over the no-slip model (offset only) and over the full-slip model (k = 0),
  // in units of the residual noise variance.
  double chi2_slip = 0.0;
  double chi2_stick = 0.0;
  int points = 0;
  // The outermost fitted point's normalised radius |p|: slip beyond it is not seen (NaN without points).
  double reach = 0.0;
};

// reference_px / current_px per track; current NaN where the track is not alive.
StickZoneFit fit_stick_zone(std::span<const Vec2> reference_px, std::span<const Vec2> current_px,
                            const ContactDisk& disk, double poisson, const StickZoneOptions& settings = {});

// The slip basis at disk point p for stick ratio k (exposed for tests): b_x (traction along +x) and b_y.
void slip_basis(Vec2 p, double k, double poisson, Vec2& b_x, Vec2& b_y);

const char* to_string(StickZoneStatus status);

}  // namespace tirstrain::strain
