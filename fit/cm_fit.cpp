#include "fit/cm_fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "core/error.hpp"
#include "core/median.hpp"

namespace tirstrain::fit {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

// Parameter layouts, one block per field: [cx, cy, theta, a, A] (stick), [cx, cy, theta, a, k, s]
// (partial slip), [cx, cy, theta, a, s] (full slip). Centre in image px, a in px, theta in rad.
constexpr int kStickParams = 5;
constexpr int kPartialParams = 6;
constexpr int kSlipParams = 5;
// Partial slip with μP held at the trial's: [cx, cy, theta, a, k]; s follows from a (s = L / a², below).
constexpr int kKnownLimitParams = 5;

// The area-preserving map M that takes the segmented ellipse onto the circle of radius √(a₁a₂), row-major.
struct Normaliser {
  double m[4] = {1.0, 0.0, 0.0, 1.0};
};

Normaliser normaliser(const ContactEllipse& e) {
  const double ratio = std::sqrt(e.semi_minor_px / e.semi_major_px);  // a/a₁ with a = √(a₁a₂)
  const double d1 = ratio, d2 = 1.0 / ratio;
  const double co = std::cos(e.angle_rad), si = std::sin(e.angle_rad);
  // Rot(φ) diag(d1, d2) Rot(−φ)
  Normaliser n;
  n.m[0] = co * co * d1 + si * si * d2;
  n.m[1] = co * si * (d1 - d2);
  n.m[2] = n.m[1];
  n.m[3] = si * si * d1 + co * co * d2;
  return n;
}

// One track's residual (model − measured), px, for field F. Partial slip with `Known` holds μP fixed at
// `known_limit` L: s = L / a² (μP = (2π/3) G s a², so L = 3μP / (2π G) in px², see known_limit_px2).
template <FieldModel F, bool Known = false>
struct TrackResidual {
  double qx, qy;  // M X
  double ux, uy;  // measured displacement
  Normaliser n;
  double nu;
  double known_limit = 0.0;

  template <typename T>
  bool operator()(const T* p, T* r) const {
    using std::cos;
    using std::sin;
    const T xi = qx - (n.m[0] * p[0] + n.m[1] * p[1]);
    const T yi = qy - (n.m[2] * p[0] + n.m[3] * p[1]);
    const T co = cos(p[2]), si = sin(p[2]);
    const T xl = co * xi + si * yi;
    const T yl = -si * xi + co * yi;
    T wx, wy;
    if constexpr (F == FieldModel::full_stick) {
      full_stick_px(xl, yl, p[3], p[4], nu, wx, wy);
    } else if constexpr (F == FieldModel::partial_slip) {
      if constexpr (Known) {
        partial_slip_px(xl, yl, p[3], p[4], T(known_limit) / (p[3] * p[3]), nu, wx, wy);
      } else {
        partial_slip_px(xl, yl, p[3], p[4], p[5], nu, wx, wy);
      }
    } else {
      partial_slip_px(xl, yl, p[3], T(0.0), p[4], nu, wx, wy);
    }
    r[0] = co * wx - si * wy - ux;
    r[1] = si * wx + co * wy - uy;
    return true;
  }
};

// The segmented contact as a measurement of the centre and of a: w (p − p_seg) / (σ_rel a_seg) for each, with
// w the tracking noise it is weighed against. Without it a is poorly determined while c is near a (only a
// thin slip annulus, at the border where tracks are fewest and noisiest, sees it), and Q = μP (1 − (c/a)³),
// μP ∝ a² inherit that; and in full stick the field inside the contact is a uniform shift that says nothing
// of the centre.
struct ContactPrior {
  double cx_px, cy_px, a_seg_px;
  double weight;  // w / (σ_rel a_seg), px per px

  template <typename T>
  bool operator()(const T* p, T* r) const {
    r[0] = weight * (p[0] - cx_px);
    r[1] = weight * (p[1] - cy_px);
    r[2] = weight * (p[3] - a_seg_px);
    return true;
  }
};

// The tracks a frame's fit uses, in the normalised frame.
struct Samples {
  std::vector<std::size_t> index;   // into the frame's track arrays
  std::vector<Vec2> q;              // M X
  std::vector<Vec2> u;              // measured displacement
  double cx_px = 0.0, cy_px = 0.0;  // the segmented ellipse's centre
  double a_seg_px = 0.0;            // and its equivalent radius √(a₁a₂)
};

bool inside_ellipse(const ContactEllipse& e, const Vec2& p, double margin) {
  const double co = std::cos(e.angle_rad), si = std::sin(e.angle_rad);
  const double dx = p.x - e.cx_px, dy = p.y - e.cy_px;
  const double along = (co * dx + si * dy) / e.semi_major_px;
  const double across = (-si * dx + co * dy) / e.semi_minor_px;
  return along * along + across * across <= margin * margin;
}

Samples select_samples(const FrameObservations& obs, const Normaliser& n, double margin) {
  Samples s;
  s.cx_px = obs.contact.cx_px;
  s.cy_px = obs.contact.cy_px;
  s.a_seg_px = std::sqrt(obs.contact.semi_major_px * obs.contact.semi_minor_px);
  for (std::size_t i = 0; i < obs.reference_px.size(); ++i) {
    const Vec2& X = obs.reference_px[i];
    const Vec2& u = obs.displacement_px[i];
    if (!(std::isfinite(X.x) && std::isfinite(X.y) && std::isfinite(u.x) && std::isfinite(u.y))) continue;
    if (!inside_ellipse(obs.contact, X, margin)) continue;
    s.index.push_back(i);
    s.q.push_back({n.m[0] * X.x + n.m[1] * X.y, n.m[2] * X.x + n.m[3] * X.y});
    s.u.push_back(u);
  }
  return s;
}

// A solved field: parameters, robust cost and the parameter covariance (scaled by the residual variance).
struct Solved {
  std::vector<double> p;
  double cost = 0.0;        // ½ Σ ρ(|r|²)
  std::vector<double> cov;  // p × p row-major; empty when the Jacobian is rank deficient
};

struct Bounds {
  std::vector<double> lower, upper;
};

template <FieldModel F, int P>
void add_residuals(ceres::Problem& problem, const Samples& s, const Normaliser& n, double nu, double* p,
                   const FitOptions& options, double known_limit) {
  if (options.radius_prior_sd > 0.0) {
    const double weight = options.prior_noise_px / (options.radius_prior_sd * s.a_seg_px);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ContactPrior, 3, P>(
                                 new ContactPrior{s.cx_px, s.cy_px, s.a_seg_px, weight}),
                             nullptr, p);
  }
  constexpr bool known = F == FieldModel::partial_slip && P == kKnownLimitParams;
  for (std::size_t i = 0; i < s.q.size(); ++i) {
    auto* cost = new ceres::AutoDiffCostFunction<TrackResidual<F, known>, 2, P>(
        new TrackResidual<F, known>{s.q[i].x, s.q[i].y, s.u[i].x, s.u[i].y, n, nu, known_limit});
    problem.AddResidualBlock(cost, new ceres::HuberLoss(options.loss_scale_px), p);
  }
}

template <FieldModel F, int P>
Solved solve_field(const Samples& s, const Normaliser& n, double nu, std::vector<double> start,
                   const Bounds& bounds, const FitOptions& options, double known_limit = 0.0) {
  ceres::Problem problem;
  Solved out;
  out.p = std::move(start);
  double* p = out.p.data();
  add_residuals<F, P>(problem, s, n, nu, p, options, known_limit);
  for (int j = 0; j < P; ++j) {
    if (std::isfinite(bounds.lower[j])) problem.SetParameterLowerBound(p, j, bounds.lower[j]);
    if (std::isfinite(bounds.upper[j])) problem.SetParameterUpperBound(p, j, bounds.upper[j]);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.logging_type = ceres::SILENT;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = options.threads;
  // c/a and Q/μP are wanted to ~1e-3: tighter tolerances only add iterations.
  so.function_tolerance = 1e-7;
  so.parameter_tolerance = 1e-7;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.cost = summary.final_cost;
  return out;
}

// Covariance (JᵀJ)⁻¹ σ² of the fitted parameters, with J the robustified Jacobian at the solution and
// σ² = 2·cost/(n − p). Computed here rather than by ceres::Covariance so that a rank-deficient Jacobian
// (a parameter the data do not determine, e.g. c/a at c = a) is a status, not a log line.
template <FieldModel F, int P>
void compute_covariance(Solved& fit, const Samples& s, const Normaliser& n, double nu,
                        const FitOptions& options, double shared, double known_limit = 0.0) {
  ceres::Problem problem;
  std::vector<double> p = fit.p;
  add_residuals<F, P>(problem, s, n, nu, p.data(), options, known_limit);
  ceres::CRSMatrix j;
  ceres::Problem::EvaluateOptions eo;
  eo.num_threads = options.threads;
  if (!problem.Evaluate(eo, nullptr, nullptr, nullptr, &j)) return;
  Eigen::Matrix<double, P, P> jtj = Eigen::Matrix<double, P, P>::Zero();
  for (int r = 0; r < j.num_rows; ++r) {
    Eigen::Matrix<double, P, 1> row = Eigen::Matrix<double, P, 1>::Zero();
    for (int e = j.rows[r]; e < j.rows[r + 1]; ++e) row(j.cols[e]) = j.values[e];
    jtj.noalias() += row * row.transpose();
  }
  // Equilibrate, then refuse a condition number the data cannot support.
  const Eigen::Matrix<double, P, 1> d = jtj.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::Matrix<double, P, P> scaled = d.asDiagonal() * jtj * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, P, P>> eig(scaled);
  const auto ev = eig.eigenvalues();
  if (!(ev.minCoeff() > 1e-12 * ev.maxCoeff())) return;
  const Eigen::Matrix<double, P, P> inv =
      d.asDiagonal() *
      (eig.eigenvectors() * ev.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose()) * d.asDiagonal();
  // Residuals that neighbours share average out only over the independent share: the scatter counts
  // `shared` times in the parameters' variance (as in the local fit's window covariance, flow/local_fit.hpp).
  const double dof = std::max(1.0, 2.0 * static_cast<double>(s.q.size()) - P);
  const double variance = shared * 2.0 * fit.cost / dof;
  fit.cov.assign(P * P, 0.0);
  for (int r = 0; r < P; ++r)
    for (int c = 0; c < P; ++c) fit.cov[r * P + c] = inv(r, c) * variance;
}

// Robust cost of the rest field (u = 0), as Ceres would report it.
double rest_cost(const Samples& s, double loss_scale_px) {
  const ceres::HuberLoss loss(loss_scale_px);
  double cost = 0.0;
  for (const Vec2& u : s.u) {
    double rho[3];
    loss.Evaluate(u.x * u.x + u.y * u.y, rho);
    cost += 0.5 * rho[0];
  }
  return cost;
}

// Where every fit starts: the ellipse's centre and equivalent radius, the mean displacement's direction,
// and the stick amplitude whose uniform shift is the mean displacement.
struct Start {
  double cx, cy, theta, a, amplitude;
};

Start initial_guess(const Samples& s, const ContactEllipse& e, double nu) {
  double mx = 0.0, my = 0.0;
  for (const Vec2& u : s.u) {
    mx += u.x;
    my += u.y;
  }
  mx /= static_cast<double>(s.u.size());
  my /= static_cast<double>(s.u.size());
  Start g;
  g.cx = e.cx_px;
  g.cy = e.cy_px;
  g.theta = std::atan2(my, mx);
  g.a = std::sqrt(e.semi_major_px * e.semi_minor_px);
  // Uniform stick shift δ = A a π (2 − ν) / 4; the mean over the contact is below δ, hence the factor.
  g.amplitude = 1.5 * std::hypot(mx, my) / (g.a * kPi * (2.0 - nu) / 4.0);
  return g;
}

Bounds geometry_bounds(const Start& g, int params) {
  const double inf = std::numeric_limits<double>::infinity();
  Bounds b{std::vector<double>(params, -inf), std::vector<double>(params, inf)};
  b.lower[0] = g.cx - 0.4 * g.a;
  b.upper[0] = g.cx + 0.4 * g.a;
  b.lower[1] = g.cy - 0.4 * g.a;
  b.upper[1] = g.cy + 0.4 * g.a;
  b.lower[3] = 0.6 * g.a;
  b.upper[3] = 1.4 * g.a;
  for (int j = 4; j < params; ++j) b.lower[j] = 0.0;
  if (params == kPartialParams) b.upper[4] = 1.0;
  return b;
}

// The three loaded fields; partial slip starts from what stick and full slip found.
struct Fits {
  Solved stick, partial, slip;
};

Fits solve_loaded_fields(const Samples& s, const Normaliser& n, const Start& g, double nu,
                         const FitOptions& options) {
  Fits f;
  f.stick = solve_field<FieldModel::full_stick, kStickParams>(
      s, n, nu, {g.cx, g.cy, g.theta, g.a, g.amplitude}, geometry_bounds(g, kStickParams), options);
  const std::vector<double>& st = f.stick.p;
  const double amp = std::max(st[4], 1e-12);
  // Full slip's centre displacement s a π (2 − ν) / 8 against the stick's shift: s = 2A.
  f.slip = solve_field<FieldModel::full_slip, kSlipParams>(s, n, nu, {st[0], st[1], st[2], st[3], 2.0 * amp},
                                                           geometry_bounds(g, kSlipParams), options);
  // Starts for c/a: near a (two, the cost is not convex in c/a there) where the stick field fits better than
  // the full-slip one, else low.
  const std::vector<double> starts =
      f.stick.cost < f.slip.cost ? std::vector<double>{0.9, 0.6} : std::vector<double>{0.4};
  for (std::size_t i = 0; i < starts.size(); ++i) {
    const double k = starts[i];
    // Same shift inside the stick zone: s (1 − k²) = 2A.
    Solved p = solve_field<FieldModel::partial_slip, kPartialParams>(
        s, n, nu, {st[0], st[1], st[2], st[3], k, 2.0 * amp / (1.0 - k * k)},
        geometry_bounds(g, kPartialParams), options);
    if (i == 0 || p.cost < f.partial.cost) f.partial = std::move(p);
  }
  return f;
}

// L = 3μP / (2π G) in px²: the known limit as TrackResidual holds it.
double known_limit_px2(const TrialLimit& limit, double m_per_px, double shear_Pa) {
  return 3.0 * limit.limit_N / (2.0 * kPi * shear_Pa * m_per_px * m_per_px);
}

// Partial slip at the known limit L, started where its stick zone shifts as far as the stick field's
// (s (1 − k²) = 2A with s = L / a²) and where the free partial-slip fit put c; the better of the two.
Solved solve_known_limit(const Samples& s, const Normaliser& n, const Start& g, double nu, const Fits& f,
                         double known_limit, const FitOptions& options) {
  Bounds b = geometry_bounds(g, kKnownLimitParams);
  b.upper[4] = 1.0;
  const std::vector<double>& st = f.stick.p;
  const double s_known = known_limit / (st[3] * st[3]);
  const double k_shift = std::sqrt(std::clamp(1.0 - 2.0 * std::max(st[4], 0.0) / s_known, 0.0, 1.0));
  Solved best;
  bool first = true;
  for (const double k : {std::clamp(k_shift, 0.05, 0.98), std::clamp(f.partial.p[4], 0.05, 0.98)}) {
    Solved p = solve_field<FieldModel::partial_slip, kKnownLimitParams>(
        s, n, nu, {st[0], st[1], st[2], st[3], k}, b, options, known_limit);
    if (first || p.cost < best.cost) best = std::move(p);
    first = false;
  }
  return best;
}

// Residuals that neighbours share are not independent evidence: with each track sharing its residual with
// `shared` tracks' worth of neighbours, the likelihood holds n / shared independent residuals.
void set_criteria(FrameFit& out, FieldModel m, double cost, int params, std::size_t residuals,
                  double shared) {
  const double n = static_cast<double>(residuals);
  const double independent = n / shared;
  const double fit_term = independent * std::log(std::max(2.0 * cost / n, 1e-300));
  out.aic[static_cast<int>(m)] = fit_term + 2.0 * params;
  out.bic[static_cast<int>(m)] = fit_term + params * std::log(independent);
}

// The residual correlation between tracks at distance d, in rings of `ring_px` out to `reach_px`, summed
// over each track's neighbours: 1 + Σ_rings ρ(ring) × (neighbours per track in the ring). The first ring
// whose correlation is not significant (below 2/√pairs) or not positive ends the sum; rings of fewer than
// 10 pairs are skipped. Clamped to [1, n / 20].
double shared_residuals(const std::vector<Vec2>& X, const std::vector<Vec2>& r, double ring_px,
                        double reach_px) {
  const std::size_t n = X.size();
  const int rings = static_cast<int>(std::ceil(reach_px / ring_px));
  std::vector<double> dot(static_cast<std::size_t>(rings), 0.0), energy(static_cast<std::size_t>(rings), 0.0);
  std::vector<double> pairs(static_cast<std::size_t>(rings), 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const double d = std::hypot(X[i].x - X[j].x, X[i].y - X[j].y);
      if (!(d < reach_px)) continue;
      const std::size_t b = static_cast<std::size_t>(d / ring_px);
      dot[b] += r[i].x * r[j].x + r[i].y * r[j].y;
      energy[b] += 0.5 * (r[i].x * r[i].x + r[i].y * r[i].y + r[j].x * r[j].x + r[j].y * r[j].y);
      pairs[b] += 1.0;
    }
  double shared = 1.0;
  for (std::size_t b = 0; b < dot.size(); ++b) {
    if (pairs[b] < 10.0 || !(energy[b] > 0.0)) continue;  // a ring closer than the spacing holds no pairs
    const double rho = dot[b] / energy[b];
    if (!(rho > 2.0 / std::sqrt(2.0 * pairs[b]))) break;
    shared += rho * 2.0 * pairs[b] / static_cast<double>(n);
  }
  return std::clamp(shared, 1.0, std::max(1.0, static_cast<double>(n) / 20.0));
}

// The partial-slip fit's residuals (the most general loaded field) at the tracks used.
double shared_residuals_of(const FrameObservations& obs, const Samples& s, const Normaliser& n, double nu,
                           const Solved& partial) {
  std::vector<Vec2> X, r;
  for (std::size_t i = 0; i < s.q.size(); ++i) {
    double res[2];
    TrackResidual<FieldModel::partial_slip>{s.q[i].x, s.q[i].y, s.u[i].x, s.u[i].y, n, nu}(partial.p.data(),
                                                                                           res);
    if (!(std::isfinite(res[0]) && std::isfinite(res[1]))) continue;
    X.push_back(obs.reference_px[s.index[i]]);
    r.push_back({res[0], res[1]});
  }
  // Rings of the tracks' own spacing (the median nearest-neighbour distance), out to a tenth of the contact's
  // diameter: far enough for overlapping subsets and local averaging, short of the field's own scale.
  std::vector<double> nearest(X.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < X.size(); ++i)
    for (std::size_t j = 0; j < X.size(); ++j)
      if (i != j) nearest[i] = std::min(nearest[i], std::hypot(X[i].x - X[j].x, X[i].y - X[j].y));
  if (X.size() < 3) return 1.0;
  const double spacing = upper_median_in_place(nearest);
  if (!(spacing > 0.0) || !std::isfinite(spacing)) return 1.0;
  return shared_residuals(X, r, spacing, std::max(2.0 * spacing, 0.2 * s.a_seg_px));
}

// Rest against any load is decided on the independent share of the residuals (`rest_bic`: the criteria
// with the residuals' measured sharing): at rest the residuals are the tracks' noise, which neighbours
// share, and counted as independent they make any loaded field's few parameters look worth their cost.
// Among the loaded fields the criteria count every residual: there the residuals' spatial correlation is
// mostly the fields' own misfit, and discounting it would discard the slip annulus' evidence.
// Without `stick_allowed` (a known limit), the loaded field is partial or full slip.
FieldModel choose_model(const FrameFit& out, const std::array<double, kFieldModels>& rest_bic,
                        bool stick_allowed) {
  const int first = static_cast<int>(stick_allowed ? FieldModel::full_stick : FieldModel::partial_slip);
  int loaded = first;
  for (int m = first + 1; m < kFieldModels; ++m)
    if (out.bic[m] < out.bic[loaded]) loaded = m;
  const int rest = static_cast<int>(FieldModel::rest);
  for (int m = rest + 1; m < kFieldModels; ++m)
    if (!(rest_bic[rest] < rest_bic[m])) return static_cast<FieldModel>(loaded);
  return FieldModel::rest;
}

// SD of g(p) by the delta method: sqrt(gradᵀ Σ grad).
double delta_sd(const std::vector<double>& cov, const std::vector<double>& grad) {
  if (cov.empty()) return kNaN;
  const std::size_t p = grad.size();
  double v = 0.0;
  for (std::size_t i = 0; i < p; ++i)
    for (std::size_t j = 0; j < p; ++j) v += grad[i] * cov[i * p + j] * grad[j];
  return std::sqrt(std::max(v, 0.0));
}

double param_sd(const Solved& s, std::size_t j) {
  return s.cov.empty() ? kNaN : std::sqrt(std::max(s.cov[j * s.p.size() + j], 0.0));
}

// Physical units of the chosen field's parameters.
struct Units {
  double m_per_px;
  double shear_Pa;
};

void report_geometry(FrameFit& out, const Solved& s, const Units& u) {
  const double mm_per_px = 1e3 * u.m_per_px;
  out.centre_x_px = {s.p[0], param_sd(s, 0)};
  out.centre_y_px = {s.p[1], param_sd(s, 1)};
  const double theta = std::remainder(s.p[2], 2.0 * kPi);
  out.direction_deg = {theta * 180.0 / kPi, param_sd(s, 2) * 180.0 / kPi};
  out.a_mm = {s.p[3] * mm_per_px, param_sd(s, 3) * mm_per_px};
}

void report_stick(FrameFit& out, const Solved& s, const Units& u) {
  report_geometry(out, s, u);
  out.c_mm = out.a_mm;
  const double a_m = s.p[3] * u.m_per_px;
  const double q = 2.0 * kPi * u.shear_Pa * a_m * a_m * s.p[4];
  out.tangential_N = {q, delta_sd(s.cov, {0, 0, 0, 2.0 * q / s.p[3], q / std::max(s.p[4], 1e-300)})};
  out.limit_N = {kNaN, kNaN};
}

// Partial slip (k free) and full slip (k = 0) share μP = (2π/3) G s a², Q = μP (1 − k³).
void report_slip(FrameFit& out, const Solved& s, const Units& u, bool partial) {
  report_geometry(out, s, u);
  const double a_px = s.p[3];
  const double k = partial ? s.p[4] : 0.0;
  const double sc = partial ? s.p[5] : s.p[4];
  const double a_m = a_px * u.m_per_px;
  const double limit = 2.0 * kPi / 3.0 * u.shear_Pa * a_m * a_m * sc;
  const double q = limit * (1.0 - k * k * k);
  if (partial) {
    const double mm_per_px = 1e3 * u.m_per_px;
    out.c_mm = {k * a_px * mm_per_px, mm_per_px * delta_sd(s.cov, {0, 0, 0, k, a_px, 0})};
    const double dq_dk = -3.0 * limit * k * k;
    out.tangential_N = {q, delta_sd(s.cov, {0, 0, 0, 2.0 * q / a_px, dq_dk, q / std::max(sc, 1e-300)})};
    out.limit_N = {limit, delta_sd(s.cov, {0, 0, 0, 2.0 * limit / a_px, 0, limit / std::max(sc, 1e-300)})};
  } else {
    out.c_mm = {0.0, 0.0};
    out.tangential_N = {q, delta_sd(s.cov, {0, 0, 0, 2.0 * q / a_px, q / std::max(sc, 1e-300)})};
    out.limit_N = {limit, out.tangential_N.sd};
  }
}

// Partial slip at the trial's μP: Q = μP (1 − k³), its SD from k's and μP's.
void report_known_limit(FrameFit& out, const Solved& s, const Units& u, const TrialLimit& limit) {
  report_geometry(out, s, u);
  const double mm_per_px = 1e3 * u.m_per_px;
  const double a_px = s.p[3], k = s.p[4];
  out.c_mm = {k * a_px * mm_per_px, mm_per_px * delta_sd(s.cov, {0, 0, 0, k, a_px})};
  const double mu_p = limit.limit_N;
  out.tangential_N = {mu_p * (1.0 - k * k * k),
                      std::hypot(3.0 * mu_p * k * k * param_sd(s, 4), (1.0 - k * k * k) * limit.sd_N)};
  out.limit_N = {mu_p, limit.sd_N};
  out.limit_from_trial = true;
}

void report_rest(FrameFit& out) {
  out.centre_x_px = out.centre_y_px = out.direction_deg = out.a_mm = out.c_mm = {kNaN, kNaN};
  out.tangential_N = {0.0, 0.0};
  out.limit_N = {kNaN, kNaN};
}

// measured − model per used track, and the RMS of its length.
template <FieldModel F>
void fill_residuals(FrameFit& out, const Samples& s, const Normaliser& n, double nu, const Solved& fit,
                    double known_limit = 0.0) {
  double sum = 0.0;
  for (std::size_t i = 0; i < s.q.size(); ++i) {
    double r[2] = {-s.u[i].x, -s.u[i].y};
    if constexpr (F == FieldModel::partial_slip) {
      if (known_limit > 0.0)
        TrackResidual<F, true>{s.q[i].x, s.q[i].y, s.u[i].x, s.u[i].y, n, nu, known_limit}(fit.p.data(), r);
      else
        TrackResidual<F>{s.q[i].x, s.q[i].y, s.u[i].x, s.u[i].y, n, nu}(fit.p.data(), r);
    } else if constexpr (F != FieldModel::rest) {
      TrackResidual<F>{s.q[i].x, s.q[i].y, s.u[i].x, s.u[i].y, n, nu}(fit.p.data(), r);
    }
    out.residual_px[s.index[i]] = {-r[0], -r[1]};
    sum += r[0] * r[0] + r[1] * r[1];
  }
  out.residual_rms_px = std::sqrt(sum / static_cast<double>(s.q.size()));
}

void validate(const FrameObservations& obs) {
  if (!(std::isfinite(obs.px_per_mm) && obs.px_per_mm > 0.0))
    throw Error("fit: px_per_mm must be finite and > 0, got " + std::to_string(obs.px_per_mm));
  if (!(std::isfinite(obs.young_Pa) && obs.young_Pa > 0.0))
    throw Error("fit: tissue E (young_Pa) must be finite and > 0, got " + std::to_string(obs.young_Pa));
  if (!(obs.poisson > -1.0 && obs.poisson < 0.5))
    throw Error("fit: tissue nu must lie in (-1, 0.5), got " + std::to_string(obs.poisson));
  if (obs.reference_px.size() != obs.displacement_px.size())
    throw Error("fit: reference and displacement track counts differ");
}

bool usable_ellipse(const ContactEllipse& e) {
  return std::isfinite(e.cx_px) && std::isfinite(e.cy_px) && std::isfinite(e.angle_rad) &&
         e.semi_major_px > 0.0 && e.semi_minor_px > 0.0 && std::isfinite(e.semi_major_px);
}

FrameFit unfitted(FitStatus status, std::size_t tracks) {
  FrameFit out;
  out.status = status;
  report_rest(out);
  out.tangential_N = {kNaN, kNaN};
  out.residual_rms_px = kNaN;
  out.aic.fill(kNaN);
  out.bic.fill(kNaN);
  out.residual_px.assign(tracks, {kNaN, kNaN});
  return out;
}

// The 90th percentile of the used tracks' distance from the fitted centre, over the fitted a.
double tracked_radius(const Samples& s, const Normaliser& n, const Solved& fit) {
  const double cx = n.m[0] * fit.p[0] + n.m[1] * fit.p[1], cy = n.m[2] * fit.p[0] + n.m[3] * fit.p[1];
  std::vector<double> r;
  r.reserve(s.q.size());
  for (const Vec2& q : s.q) r.push_back(std::hypot(q.x - cx, q.y - cy) / fit.p[3]);
  const std::size_t at = (r.size() * 9) / 10;
  std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(at), r.end());
  return r[at];
}

// The largest displacement the reported field gives a used track (measured − residual), px.
double largest_field_px(const FrameFit& out, const Samples& s) {
  double largest = 0.0;
  for (std::size_t i = 0; i < s.q.size(); ++i) {
    const Vec2& r = out.residual_px[s.index[i]];
    largest = std::max(largest, std::hypot(s.u[i].x - r.x, s.u[i].y - r.y));
  }
  return largest;
}

// The partial-slip slot's fit: free, or at the trial's limit (`known_limit` > 0).
struct PartialChoice {
  const TrialLimit* limit = nullptr;
  double known_limit = 0.0;
};

void report_chosen(FrameFit& out, Fits& f, const Samples& s, const Normaliser& n, double nu, const Units& u,
                   const FitOptions& options, const PartialChoice& partial) {
  const Solved* chosen = nullptr;
  switch (out.model) {
    case FieldModel::rest:
      report_rest(out);
      fill_residuals<FieldModel::rest>(out, s, n, nu, f.stick);
      out.tracked_radius = kNaN;
      return;
    case FieldModel::full_stick:
      compute_covariance<FieldModel::full_stick, kStickParams>(f.stick, s, n, nu, options,
                                                               out.shared_residuals);
      report_stick(out, f.stick, u);
      fill_residuals<FieldModel::full_stick>(out, s, n, nu, f.stick);
      chosen = &f.stick;
      break;
    case FieldModel::partial_slip:
      if (partial.limit) {
        compute_covariance<FieldModel::partial_slip, kKnownLimitParams>(
            f.partial, s, n, nu, options, out.shared_residuals, partial.known_limit);
        report_known_limit(out, f.partial, u, *partial.limit);
      } else {
        compute_covariance<FieldModel::partial_slip, kPartialParams>(f.partial, s, n, nu, options,
                                                                     out.shared_residuals);
        report_slip(out, f.partial, u, true);
      }
      fill_residuals<FieldModel::partial_slip>(out, s, n, nu, f.partial, partial.known_limit);
      chosen = &f.partial;
      break;
    case FieldModel::full_slip:
      compute_covariance<FieldModel::full_slip, kSlipParams>(f.slip, s, n, nu, options, out.shared_residuals);
      report_slip(out, f.slip, u, false);
      fill_residuals<FieldModel::full_slip>(out, s, n, nu, f.slip);
      chosen = &f.slip;
      break;
  }
  out.tracked_radius = tracked_radius(s, n, *chosen);
  if (chosen->cov.empty()) out.status = FitStatus::no_covariance;
}

}  // namespace

const char* fit_status_name(FitStatus s) {
  switch (s) {
    case FitStatus::ok:
      return "ok";
    case FitStatus::no_contact:
      return "no_contact";
    case FitStatus::too_few_tracks:
      return "too_few_tracks";
    case FitStatus::no_covariance:
      return "no_covariance";
  }
  return "unknown";
}

FrameFit fit_frame(const FrameObservations& obs, const FitOptions& options, const TrialLimit* limit) {
  validate(obs);
  const std::size_t tracks = obs.reference_px.size();
  if (!obs.has_contact || !usable_ellipse(obs.contact)) return unfitted(FitStatus::no_contact, tracks);
  const Normaliser n = normaliser(obs.contact);
  const Samples s = select_samples(obs, n, options.contact_margin);
  if (static_cast<int>(s.q.size()) < std::max(options.min_tracks, kPartialParams + 1))
    return unfitted(FitStatus::too_few_tracks, tracks);

  const double nu = obs.poisson;
  const Start g = initial_guess(s, obs.contact, nu);
  Fits f = solve_loaded_fields(s, n, g, nu, options);
  FrameFit out;
  out.tracks_used = static_cast<int>(s.q.size());
  out.residual_px.assign(tracks, {kNaN, kNaN});
  const std::size_t residuals = 2 * s.q.size();
  out.shared_residuals = shared_residuals_of(obs, s, n, nu, f.partial);
  std::array<double, kFieldModels> costs = {rest_cost(s, options.loss_scale_px), f.stick.cost, f.partial.cost,
                                            f.slip.cost};
  std::array<int, kFieldModels> params = {0, kStickParams, kPartialParams, kSlipParams};
  const Units u{1e-3 / obs.px_per_mm, obs.young_Pa / (2.0 * (1.0 + obs.poisson))};
  PartialChoice partial;
  const bool has_limit = limit != nullptr && limit->limit_N > 0.0;
  if (has_limit) {
    // Partial slip at the trial's μP takes the partial-slip slot.
    const double known = known_limit_px2(*limit, u.m_per_px, u.shear_Pa);
    f.partial = solve_known_limit(s, n, g, nu, f, known, options);
    costs[static_cast<int>(FieldModel::partial_slip)] = f.partial.cost;
    params[static_cast<int>(FieldModel::partial_slip)] = kKnownLimitParams;
    partial = {limit, known};
  }
  FrameFit shared;
  for (int m = 0; m < kFieldModels; ++m) {
    const auto model = static_cast<FieldModel>(m);
    set_criteria(out, model, costs[static_cast<std::size_t>(m)], params[static_cast<std::size_t>(m)],
                 residuals, 1.0);
    set_criteria(shared, model, costs[static_cast<std::size_t>(m)], params[static_cast<std::size_t>(m)],
                 residuals, out.shared_residuals);
  }
  out.model = choose_model(out, shared.bic, !has_limit);
  report_chosen(out, f, s, n, nu, u, options, partial);
  if (out.model != FieldModel::rest && largest_field_px(out, s) < options.rest_tolerance_px) {
    out.model = FieldModel::rest;
    out.status = FitStatus::ok;
    report_chosen(out, f, s, n, nu, u, options, partial);
  }
  return out;
}

}  // namespace tirstrain::fit
