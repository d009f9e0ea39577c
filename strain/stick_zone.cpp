#include "strain/stick_zone.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "core/median.hpp"

namespace tirstrain::strain {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

// φ(ρ) and d(ρ) of the building block U[q0, a] (docs/model.md), ρ = r / a.
void phi_d(double rho, double& phi, double& d) {
  if (rho <= 1.0) {
    phi = 0.5 * kPi * (2.0 - rho * rho);
    d = -0.5 * kPi * rho * rho;
    return;
  }
  if (rho > 1e4) {
    const double i1 = 1.0 / rho, i3 = i1 * i1 * i1;
    phi = 4.0 / 3.0 * i1 + 2.0 / 15.0 * i3;
    d = -8.0 / 3.0 * i1 + 4.0 / 5.0 * i3;
    return;
  }
  const double as = std::asin(std::clamp(1.0 / rho, -1.0, 1.0));
  const double root = std::sqrt((rho - 1.0) * (rho + 1.0));
  phi = (2.0 - rho * rho) * as + root;
  d = -rho * rho * as + root * (1.0 - 2.0 / (rho * rho));
}

// A track in disk coordinates with what does not depend on k precomputed.
struct Point {
  Vec2 p;  // disk coordinates
  Vec2 d;  // measured displacement minus the mean displacement of all points, pixels
  double rho = 0.0, c2 = 1.0, s2 = 0.0, phi_a = 0.0, d_a = 0.0;
};

Point make_point(Vec2 p, Vec2 d) {
  Point q{p, d};
  q.rho = std::hypot(p.x, p.y);
  if (q.rho > 0.0) {
    q.c2 = (p.x * p.x - p.y * p.y) / (q.rho * q.rho);
    q.s2 = 2.0 * p.x * p.y / (q.rho * q.rho);
  }
  phi_d(q.rho, q.phi_a, q.d_a);
  return q;
}

// slip_basis() on a precomputed point; false (and zeros) inside the stick zone.
bool basis(const Point& q, double k, double nu, Vec2& b_x, Vec2& b_y) {
  if (!(q.rho > k)) {
    b_x = b_y = {};
    return false;
  }
  double big_phi = q.phi_a, big_d = q.d_a;
  if (k > 0.0) {
    double phi_c = 0.0, d_c = 0.0;
    phi_d(q.rho / k, phi_c, d_c);
    big_phi -= k * k * phi_c;
    big_d -= k * k * d_c;
  }
  const double delta = kPi * (1.0 - 0.5 * nu) * (1.0 - k * k);
  const double radial = (1.0 - 0.5 * nu) * big_phi - delta;
  const double cross = -0.25 * nu * big_d * q.s2;
  b_x = {radial - 0.25 * nu * big_d * q.c2, cross};
  b_y = {cross, radial + 0.25 * nu * big_d * q.c2};
  return true;
}

struct Solution {
  double rss = std::numeric_limits<double>::infinity();
  std::array<double, 4> theta{};  // t_x, t_y, A_x, A_y
  bool slip_determined = false;   // the slip amplitudes are determined (some point outside the stick zone)
};

// Solves the 4×4 symmetric system by Gaussian elimination with partial pivoting; false when singular.
bool solve4(std::array<std::array<double, 5>, 4> m, std::array<double, 4>& x) {
  double scale = 0.0;
  for (const auto& row : m)
    for (int j = 0; j < 4; ++j) scale = std::max(scale, std::abs(row[static_cast<std::size_t>(j)]));
  if (!(scale > 0.0)) return false;
  for (std::size_t col = 0; col < 4; ++col) {
    std::size_t pivot = col;
    for (std::size_t r = col + 1; r < 4; ++r)
      if (std::abs(m[r][col]) > std::abs(m[pivot][col])) pivot = r;
    if (std::abs(m[pivot][col]) < 1e-12 * scale) return false;
    std::swap(m[pivot], m[col]);
    for (std::size_t r = col + 1; r < 4; ++r) {
      const double f = m[r][col] / m[col][col];
      for (std::size_t c = col; c < 5; ++c) m[r][c] -= f * m[col][c];
    }
  }
  for (std::size_t i = 4; i-- > 0;) {
    double s = m[i][4];
    for (std::size_t c = i + 1; c < 4; ++c) s -= m[i][c] * x[c];
    x[i] = s / m[i][i];
  }
  return true;
}

Solution solve(const std::vector<Point>& points, double k, double poisson) {
  std::array<std::array<double, 5>, 4> m{};
  Vec2 sum_d;
  double sum_d2 = 0.0;
  bool any_slip = false;
  for (const Point& q : points) {
    Vec2 bx, by;
    if (basis(q, k, poisson, bx, by)) any_slip = true;
    // Rows of the Jacobian: [1, 0, bx.x, by.x] and [0, 1, bx.y, by.y].
    const double jx[4] = {1.0, 0.0, bx.x, by.x}, jy[4] = {0.0, 1.0, bx.y, by.y};
    for (std::size_t i = 0; i < 4; ++i) {
      for (std::size_t j = 0; j < 4; ++j) m[i][j] += jx[i] * jx[j] + jy[i] * jy[j];
      m[i][4] += jx[i] * q.d.x + jy[i] * q.d.y;
    }
    sum_d.x += q.d.x;
    sum_d.y += q.d.y;
    sum_d2 += q.d.x * q.d.x + q.d.y * q.d.y;
  }
  Solution s;
  const double n = static_cast<double>(points.size());
  if (!any_slip || !solve4(m, s.theta)) {
    s.theta = {sum_d.x / n, sum_d.y / n, 0.0, 0.0};
    s.rss = sum_d2 - (sum_d.x * sum_d.x + sum_d.y * sum_d.y) / n;
  } else {
    s.slip_determined = true;
    // At the least-squares solution RSS = Σ|d|² − θ·Jᵀd (the displacements are centred, so no large
    // common offset cancels here).
    s.rss = sum_d2;
    for (std::size_t i = 0; i < 4; ++i) s.rss -= s.theta[i] * m[i][4];
  }
  s.rss = std::max(s.rss, 0.0);
  return s;
}

struct Best {
  double k = 1.0;
  Solution solution;
};

Best minimise(const std::vector<Point>& points, double poisson, const StickZoneOptions& settings) {
  const int grid = std::max(settings.grid, 4);  // RSS(k) is smooth: a coarse grid brackets the minimum
  std::vector<double> rss(static_cast<std::size_t>(grid) + 1);
  std::size_t arg = 0;
  for (int i = 0; i <= grid; ++i) {
    rss[static_cast<std::size_t>(i)] = solve(points, static_cast<double>(i) / grid, poisson).rss;
    if (rss[static_cast<std::size_t>(i)] < rss[arg]) arg = static_cast<std::size_t>(i);
  }
  // Golden-section refinement in the bracket around the grid minimum.
  double lo = static_cast<double>(arg == 0 ? 0 : arg - 1) / grid;
  double hi = static_cast<double>(std::min<std::size_t>(arg + 1, static_cast<std::size_t>(grid))) / grid;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = solve(points, x1, poisson).rss, f2 = solve(points, x2, poisson).rss;
  while (hi - lo > 2e-4) {  // c to 2e-4 a: 0.03 px on a 150 px contact
    if (f1 <= f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = solve(points, x1, poisson).rss;
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = solve(points, x2, poisson).rss;
    }
  }
  Best best;
  best.k = static_cast<double>(arg) / grid;
  best.solution = solve(points, best.k, poisson);
  const double k_refined = 0.5 * (lo + hi);
  Solution refined = solve(points, k_refined, poisson);
  if (refined.rss <= best.solution.rss) {
    best.k = k_refined;
    best.solution = refined;
  }
  return best;
}

}  // namespace

const char* to_string(StickZoneStatus status) {
  switch (status) {
    case StickZoneStatus::kFit:
      return "fit";
    case StickZoneStatus::kNoSlip:
      return "no_slip";
    case StickZoneStatus::kTooFewPoints:
      return "too_few_points";
    case StickZoneStatus::kSlipBeyondTracks:
      return "slip_beyond_tracks";
  }
  return "?";
}

ContactDisk contact_disk(Vec2 centre_px, double semi_major_px, double semi_minor_px, double angle_rad) {
  ContactDisk disk;
  disk.centre_px = centre_px;
  if (!(semi_major_px > 0.0) || !(semi_minor_px > 0.0)) {
    disk.to_disk = {kNaN, kNaN, kNaN, kNaN};
    disk.radius_px = kNaN;
    return disk;
  }
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  const double sx = 1.0 / semi_major_px, sy = 1.0 / semi_minor_px;
  // R(φ) diag(sx, sy) R(−φ).
  disk.to_disk = {c * c * sx + s * s * sy, c * s * (sx - sy), c * s * (sx - sy), s * s * sx + c * c * sy};
  disk.radius_px = std::sqrt(semi_major_px * semi_minor_px);
  return disk;
}

void slip_basis(Vec2 p, double k, double poisson, Vec2& b_x, Vec2& b_y) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    b_x = b_y = {};
    return;
  }
  basis(make_point(p, {}), k, poisson, b_x, b_y);
}

namespace {

// The tracks inside `extent` of the contact, in the contact's unit-disk frame, with their displacements
// centred (the stuck-core shift absorbs the mean, returned in `mean`).
std::vector<Point> disk_points(std::span<const Vec2> reference_px, std::span<const Vec2> current_px,
                               const ContactDisk& disk, double extent, Vec2& mean) {
  std::vector<Point> points;
  const std::size_t n = std::min(reference_px.size(), current_px.size());
  for (std::size_t j = 0; j < n; ++j) {
    const Vec2 X = reference_px[j], x = current_px[j];
    if (!std::isfinite(X.x) || !std::isfinite(X.y) || !std::isfinite(x.x) || !std::isfinite(x.y)) continue;
    const double dx = X.x - disk.centre_px.x, dy = X.y - disk.centre_px.y;
    const Vec2 p{disk.to_disk.xx * dx + disk.to_disk.xy * dy, disk.to_disk.yx * dx + disk.to_disk.yy * dy};
    if (std::hypot(p.x, p.y) > extent) continue;
    points.push_back({p, {x.x - X.x, x.y - X.y}});
  }
  mean = {};
  for (const Point& q : points) {
    mean.x += q.d.x / static_cast<double>(points.size());
    mean.y += q.d.y / static_cast<double>(points.size());
  }
  // Precomputes what does not depend on k.
  for (Point& q : points) q = make_point(q.p, {q.d.x - mean.x, q.d.y - mean.y});
  return points;
}

// One pass of outlier rejection (lost or mismatched tracks): residuals beyond 5 σ, σ from the median
// residual norm (a 2-D Gaussian residual's norm has median 1.1774 σ); the fit again without them.
void reject_outliers(std::vector<Point>& points, double poisson, const StickZoneOptions& settings,
                     Best& best) {
  std::vector<double> norms;
  norms.reserve(points.size());
  for (const Point& q : points) {
    Vec2 bx, by;
    basis(q, best.k, poisson, bx, by);
    const auto& t = best.solution.theta;
    norms.push_back(
        std::hypot(q.d.x - t[0] - t[2] * bx.x - t[3] * by.x, q.d.y - t[1] - t[2] * bx.y - t[3] * by.y));
  }
  std::vector<double> sorted = norms;
  const double sigma = upper_median_in_place(sorted) / 1.1774;
  const double limit = std::max(5.0 * sigma, 1e-9);
  std::vector<Point> kept;
  kept.reserve(points.size());
  for (std::size_t j = 0; j < points.size(); ++j)
    if (norms[j] <= limit) kept.push_back(points[j]);
  if (kept.size() < points.size() && static_cast<int>(kept.size()) >= std::max(settings.min_points, 3)) {
    points = std::move(kept);
    best = minimise(points, poisson, settings);
  }
}

// The largest slip the fitted field predicts at any of the points.
double max_predicted_slip(const std::vector<Point>& points, const Best& best, double poisson) {
  const auto& theta = best.solution.theta;
  double max_slip = 0.0;
  for (const Point& q : points) {
    Vec2 bx, by;
    basis(q, best.k, poisson, bx, by);
    max_slip =
        std::max(max_slip, std::hypot(theta[2] * bx.x + theta[3] * by.x, theta[2] * bx.y + theta[3] * by.y));
  }
  return max_slip;
}

// A slip or a core shift counts when it exceeds this: `significance` × the residual RMS, and `min_slip_px`.
double significant_px(const StickZoneFit& out, const StickZoneOptions& settings) {
  return std::max(settings.significance * out.residual_rms_px, settings.min_slip_px);
}

// Slip is detected when the fit explains clearly more than the noise, predicts slip well above it, and the
// stuck core has moved along the fitted traction (in Cattaneo–Mindlin the core shifts by
// δ = π(1 − ν/2)(1 − k²)·|A| along A): a tracking bias at rest (a ring of small systematic errors near the
// border) must not read as slip.
bool slip_detected(const StickZoneFit& out, const Best& best, const StickZoneOptions& settings) {
  const auto& theta = best.solution.theta;
  const double floor_px = significant_px(out, settings);
  const Vec2 t = out.shift_px;
  const double shift = std::hypot(t.x, t.y), amplitude = std::hypot(theta[2], theta[3]);
  const bool core_moved = shift > floor_px && t.x * theta[2] + t.y * theta[3] > 0.5 * shift * amplitude;
  return best.solution.slip_determined && out.chi2_slip >= settings.chi2_slip && out.max_slip_px > floor_px &&
         core_moved;
}

// The largest normalised radius among the fitted points.
double reach_of(const std::vector<Point>& points) {
  double reach = 0.0;
  for (const Point& q : points) reach = std::max(reach, q.rho);
  return reach;
}

}  // namespace

StickZoneFit fit_stick_zone(std::span<const Vec2> reference_px, std::span<const Vec2> current_px,
                            const ContactDisk& disk, double poisson, const StickZoneOptions& settings) {
  StickZoneFit out;
  out.ratio = out.radius_px = out.residual_rms_px = out.max_slip_px = out.reach = kNaN;
  out.shift_px = out.amplitude_px = {kNaN, kNaN};
  if (!(disk.radius_px > 0.0)) return out;
  Vec2 mean;
  std::vector<Point> points = disk_points(reference_px, current_px, disk, settings.extent, mean);
  if (static_cast<int>(points.size()) < std::max(settings.min_points, 3)) {
    out.points = static_cast<int>(points.size());
    return out;
  }
  Best best = minimise(points, poisson, settings);
  reject_outliers(points, poisson, settings, best);

  // Model selection against the two boundary models, each by its residual decrease in units of the noise
  // variance: the offset-only field (no slip, c = a) and the single-block field (full slip, c = 0).
  const double dof = std::max(1.0, 2.0 * static_cast<double>(points.size()) - 4.0);
  const double noise_var = std::max(best.solution.rss / dof, 1e-30);
  const Solution no_slip = solve(points, 1.0, poisson);
  const Solution full_slip = solve(points, 0.0, poisson);
  out.chi2_slip = (no_slip.rss - best.solution.rss) / noise_var;
  out.chi2_stick = (full_slip.rss - best.solution.rss) / noise_var;
  if (best.k > 0.0 && out.chi2_stick < settings.chi2_stick) {
    best.k = 0.0;
    best.solution = full_slip;
  }
  const auto& theta = best.solution.theta;
  out.points = static_cast<int>(points.size());
  out.reach = reach_of(points);
  out.shift_px = {theta[0] + mean.x, theta[1] + mean.y};
  out.amplitude_px = {theta[2], theta[3]};
  out.residual_rms_px = std::sqrt(best.solution.rss / dof);
  out.max_slip_px = max_predicted_slip(points, best, poisson);
  if (slip_detected(out, best, settings)) {
    out.status = StickZoneStatus::kFit;
    out.ratio = best.k;
  } else if (std::hypot(out.shift_px.x, out.shift_px.y) > significant_px(out, settings)) {
    out.status = StickZoneStatus::kSlipBeyondTracks;
    out.ratio = kNaN;
    out.amplitude_px = {0.0, 0.0};
  } else {
    out.status = StickZoneStatus::kNoSlip;
    out.ratio = 1.0;
    out.amplitude_px = {0.0, 0.0};
  }
  out.radius_px = out.ratio * disk.radius_px;
  return out;
}

}  // namespace tirstrain::strain
