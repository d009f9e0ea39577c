#include "signals/mechanics.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <Eigen/Dense>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

using cplx = std::complex<double>;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

}  // namespace

ImpedanceSpectrum mechanical_impedance(const std::vector<double>& force_N, const std::vector<double>& motion,
                                       double sample_rate_Hz, const WelchOptions& options, MotionKind kind) {
  const TransferEstimate est = transfer_estimate(force_N, motion, sample_rate_Hz, options);
  const bool velocity = kind == MotionKind::velocity_m_s;
  ImpedanceSpectrum z;
  z.freq_Hz = est.freq_Hz;
  z.z_Ns_m.assign(est.freq_Hz.size(), cplx(0.0, 0.0));
  z.coherence = est.coherence;
  for (std::size_t i = 0; i < est.freq_Hz.size(); ++i) {
    if (std::abs(est.h1[i]) > 0.0) {
      z.z_Ns_m[i] = (velocity ? cplx(1.0, 0.0) : cplx(0.0, kTwoPi * est.freq_Hz[i])) / est.h1[i];
    } else {
      z.coherence[i] = 0.0;
    }
  }
  return z;
}

FingerImpedance finger_impedance(const ImpedanceSpectrum& loaded, const ImpedanceSpectrum* unloaded) {
  if (unloaded) {
    if (unloaded->freq_Hz.size() != loaded.freq_Hz.size() ||
        (!loaded.freq_Hz.empty() &&
         std::abs(unloaded->freq_Hz.back() - loaded.freq_Hz.back()) > 1e-9 * std::abs(loaded.freq_Hz.back())))
      throw Error(
          "loaded and unloaded recordings give different frequency axes: use the same sample rate and "
          "segment",
          {.key = "unloaded"});
  }
  FingerImpedance out;
  const std::size_t nb = loaded.freq_Hz.size();
  out.freq_Hz = loaded.freq_Hz;
  out.z_Ns_m.resize(nb);
  out.mass_kg.assign(nb, 0.0);
  out.damping_Ns_m.assign(nb, 0.0);
  out.damping_ratio.assign(nb, 0.0);
  out.coherence = loaded.coherence;
  for (std::size_t i = 0; i < nb; ++i) {
    cplx z = loaded.z_Ns_m[i];
    if (unloaded) {
      z -= unloaded->z_Ns_m[i];
      out.coherence[i] = std::min(out.coherence[i], unloaded->coherence[i]);
    }
    out.z_Ns_m[i] = z;
    const double omega = kTwoPi * out.freq_Hz[i];
    out.damping_Ns_m[i] = z.real();
    if (omega > 0.0) out.mass_kg[i] = z.imag() / omega;
    const double m_omega = out.mass_kg[i] * omega;
    if (m_omega != 0.0) out.damping_ratio[i] = z.real() / (2.0 * m_omega);
  }
  return out;
}

double MassSpringDamper::natural_frequency_Hz() const {
  return m_kg > 0.0 && k_N_m > 0.0 ? std::sqrt(k_N_m / m_kg) / kTwoPi : 0.0;
}

double MassSpringDamper::damping_ratio() const {
  return m_kg > 0.0 && k_N_m > 0.0 ? c_Ns_m / (2.0 * std::sqrt(k_N_m * m_kg)) : 0.0;
}

std::complex<double> MassSpringDamper::compliance_m_N(double f_Hz) const {
  const double omega = kTwoPi * f_Hz;
  return 1.0 / cplx(k_N_m - m_kg * omega * omega, c_Ns_m * omega);
}

MckFit fit_mass_spring_damper(const TransferEstimate& force_to_accel, const MckFitOptions& options) {
  std::vector<cplx> dyn(force_to_accel.freq_Hz.size(), cplx(0.0, 0.0));
  std::vector<double> coherence = force_to_accel.coherence;
  for (std::size_t i = 0; i < dyn.size(); ++i) {
    const double omega = kTwoPi * force_to_accel.freq_Hz[i];
    if (std::abs(force_to_accel.h1[i]) > 0.0)
      dyn[i] = -omega * omega / force_to_accel.h1[i];
    else
      coherence[i] = 0.0;
  }
  return fit_mass_spring_damper(force_to_accel.freq_Hz, dyn, coherence, options);
}

MckFit fit_mass_spring_damper(const std::vector<double>& f,
                              const std::vector<std::complex<double>>& dynamic_stiffness_N_m,
                              const std::vector<double>& coherence, const MckFitOptions& options) {
  if (f.empty() || dynamic_stiffness_N_m.size() != f.size() || coherence.size() != f.size())
    throw Error("internal: frequency, stiffness and coherence vectors differ in length");
  const double high = options.band_high_Hz > 0.0 ? options.band_high_Hz : f.back();
  std::vector<std::size_t> bins;
  for (std::size_t i = 1; i < f.size(); ++i)
    if (f[i] >= options.band_low_Hz && f[i] <= high && coherence[i] >= options.min_coherence &&
        std::abs(dynamic_stiffness_N_m[i]) > 0.0)
      bins.push_back(i);
  if (bins.size() < 3)
    throw Error("mass-spring-damper fit needs at least 3 frequency bins with coherence >= " +
                    std::to_string(options.min_coherence) + " in the band; found " +
                    std::to_string(bins.size()),
                {.key = "min_coherence"});
  const bool fixed_k = options.fixed_stiffness_N_m.has_value();
  const double k_fixed = fixed_k ? *options.fixed_stiffness_N_m : 0.0;
  if (fixed_k && !std::isfinite(k_fixed))
    throw Error("fixed stiffness must be a finite number of N/m", {.key = "fixed_stiffness_N_m"});
  // Unknowns: (k, m, c), or (m, c) with k fixed and moved to the right-hand side.
  const Eigen::Index cols = fixed_k ? 2 : 3, col_m = fixed_k ? 0 : 1, col_c = col_m + 1;
  const Eigen::Index rows = static_cast<Eigen::Index>(2 * bins.size());
  Eigen::MatrixXd design = Eigen::MatrixXd::Zero(rows, cols);
  Eigen::VectorXd rhs(rows);
  for (std::size_t r = 0; r < bins.size(); ++r) {
    const std::size_t i = bins[r];
    const double omega = kTwoPi * f[i];
    const cplx dyn = dynamic_stiffness_N_m[i];
    const double w = 1.0 / std::abs(dyn);
    const Eigen::Index re = static_cast<Eigen::Index>(2 * r), im = re + 1;
    if (!fixed_k) design(re, 0) = w;
    design(re, col_m) = -omega * omega * w;
    rhs(re) = (dyn.real() - k_fixed) * w;
    design(im, col_c) = omega * w;
    rhs(im) = dyn.imag() * w;
  }
  // Columns differ by orders of magnitude (1 vs ω²); equilibrate before the QR solve.
  Eigen::VectorXd scale = design.colwise().norm().transpose();
  for (Eigen::Index j = 0; j < cols; ++j)
    if (scale(j) == 0.0) scale(j) = 1.0;
  const Eigen::MatrixXd scaled = design * scale.cwiseInverse().asDiagonal();
  const Eigen::VectorXd sol = scaled.colPivHouseholderQr().solve(rhs).cwiseQuotient(scale);
  MckFit fit;
  fit.mck = {sol(col_m), sol(col_c), fixed_k ? k_fixed : sol(0)};
  fit.stiffness_fixed = fixed_k;
  fit.frequencies_used = bins.size();
  fit.band_low_Hz = f[bins.front()];
  fit.band_high_Hz = f[bins.back()];
  const double norm = rhs.norm();
  const Eigen::VectorXd residual = design * sol - rhs;
  fit.relative_residual = norm > 0.0 ? residual.norm() / norm : 0.0;
  // Parameter covariance σ²(AᵀA)⁻¹ in the scaled columns, then back to the parameters' units.
  const double dof = static_cast<double>(rows - cols);
  const double variance = dof > 0.0 ? residual.squaredNorm() / dof : 0.0;
  const Eigen::MatrixXd inv =
      (scaled.transpose() * scaled).ldlt().solve(Eigen::MatrixXd::Identity(cols, cols));
  const Eigen::MatrixXd cov =
      variance * scale.cwiseInverse().asDiagonal() * inv * scale.cwiseInverse().asDiagonal();
  fit.m_sd_kg = std::sqrt(std::max(0.0, cov(col_m, col_m)));
  fit.c_sd_Ns_m = std::sqrt(std::max(0.0, cov(col_c, col_c)));
  if (!fixed_k) {
    fit.k_sd_N_m = std::sqrt(std::max(0.0, cov(0, 0)));
    // The correlation follows from the design alone (σ² cancels), so it is defined even for a perfect fit.
    fit.m_k_correlation = inv(0, col_m) / std::sqrt(inv(0, 0) * inv(col_m, col_m));
  }
  return fit;
}

MckFit fit_mass_spring_damper(const FingerImpedance& finger, const MckFitOptions& options) {
  std::vector<cplx> dyn(finger.freq_Hz.size());
  for (std::size_t k = 0; k < dyn.size(); ++k)
    dyn[k] = cplx(0.0, kTwoPi * finger.freq_Hz[k]) * finger.z_Ns_m[k];
  return fit_mass_spring_damper(finger.freq_Hz, dyn, finger.coherence, options);
}

MckFit fit_mass_spring_damper(const std::vector<double>& force_N, const std::vector<double>& accel_m_s2,
                              double sample_rate_Hz, const WelchOptions& welch,
                              const MckFitOptions& options) {
  return fit_mass_spring_damper(transfer_estimate(force_N, accel_m_s2, sample_rate_Hz, welch), options);
}

PadTransfer calibrate_pad_transfer(const std::vector<double>& pad_accel_m_s2,
                                   const std::vector<double>& side_accel_m_s2, double sample_rate_Hz,
                                   const WelchOptions& options, double min_coherence) {
  const TransferEstimate est = transfer_estimate(pad_accel_m_s2, side_accel_m_s2, sample_rate_Hz, options);
  PadTransfer g;
  g.freq_Hz = est.freq_Hz;
  g.g1 = est.h1;
  g.coherence = est.coherence;
  g.valid.assign(g.freq_Hz.size(), 0);
  std::size_t best_lo = 0, best_len = 0;
  for (std::size_t i = 1; i < g.freq_Hz.size(); ++i)
    g.valid[i] = g.coherence[i] >= min_coherence && std::abs(g.g1[i]) > 0.0;
  for (std::size_t i = 1; i < g.freq_Hz.size();) {
    if (!g.valid[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < g.freq_Hz.size() && g.valid[j + 1]) ++j;
    if (j - i + 1 > best_len) {
      best_len = j - i + 1;
      best_lo = i;
    }
    i = j + 1;
  }
  if (best_len == 0)
    throw Error(
        "pad-to-side calibration: no frequency bin reaches coherence " + std::to_string(min_coherence),
        {.key = "min_coherence"});
  g.band_low_Hz = g.freq_Hz[best_lo];
  g.band_high_Hz = g.freq_Hz[best_lo + best_len - 1];
  return g;
}

std::vector<double> pad_displacement_psd_from_side(const PadTransfer& g1,
                                                   const std::vector<double>& side_psd) {
  if (side_psd.size() != g1.freq_Hz.size())
    throw Error(
        "side-accelerometer spectrum and calibration have different frequency axes: use the same segment",
        {.key = "segment"});
  std::vector<double> out(side_psd.size(), 0.0);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (!g1.valid[i]) continue;
    const double omega = kTwoPi * g1.freq_Hz[i];
    out[i] = side_psd[i] / (omega * omega * omega * omega * std::norm(g1.g1[i]));
  }
  return out;
}

std::vector<double> pad_displacement_psd_from_force(const std::vector<double>& freq_Hz,
                                                    const std::vector<double>& force_psd,
                                                    const MassSpringDamper& mck) {
  std::vector<double> out(force_psd.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = force_psd[i] * std::norm(mck.compliance_m_N(freq_Hz[i]));
  return out;
}

double band_rms(const std::vector<double>& freq_Hz, const std::vector<double>& psd, double low_Hz,
                double high_Hz) {
  if (freq_Hz.size() < 2) return 0.0;
  const double df = freq_Hz[1] - freq_Hz[0];
  double sum = 0.0;
  for (std::size_t i = 0; i < freq_Hz.size(); ++i)
    if (freq_Hz[i] >= low_Hz && freq_Hz[i] < high_Hz) sum += psd[i] * df;
  return std::sqrt(sum);
}

}  // namespace tirstrain::signals
