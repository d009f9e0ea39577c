#pragma once
// Fingertip mechanics from force and accelerometer channels, all built on the Welch/H1 estimates of
// signals/spectral.hpp (so the same SciPy conventions hold):
//   - mechanical impedance Z(jω) = F/V = jω·F/A of a finger on a vibrating plate, the finger's share
//     Z_f = Z_loaded − Z_unloaded, and per frequency m = Im(Z_f)/ω, b = Re(Z_f), ζ = b/(2mω);
//   - a spring–mass–damper G2 = X/F = 1/(m s² + c s + k) fitted from force and pad acceleration by linear
//     least squares on the real and imaginary parts of F/X = jωZ = (k − mω²) + jωc;
//   - the pad→side accelerometer transfer G1 = A_side/A_pad calibrated from a two-accelerometer sweep,
//     with coherence and its valid band, and the pad displacement X_p(ω) = A_side(ω)/(−ω²·G1(ω)) compared
//     with the force-driven estimate X_p = G2·F per frequency band.
#include <complex>
#include <cstddef>
#include <optional>
#include <vector>

#include "signals/spectral.hpp"

namespace tirstrain::signals {

struct ImpedanceSpectrum {
  std::vector<double> freq_Hz;
  std::vector<std::complex<double>> z_Ns_m;  // F/V
  std::vector<double> coherence;             // force–acceleration coherence
};

// What the motion channel measures: a plate accelerometer, or a velocity (a laser vibrometer).
enum class MotionKind { acceleration_m_s2, velocity_m_s };

// Z = jω / H1(F→A) from acceleration, Z = 1 / H1(F→V) from velocity. Bins where the force has no power
// (H1 = 0) get Z = 0 and coherence 0.
ImpedanceSpectrum mechanical_impedance(const std::vector<double>& force_N, const std::vector<double>& motion,
                                       double sample_rate_Hz, const WelchOptions& options,
                                       MotionKind kind = MotionKind::acceleration_m_s2);

struct FingerImpedance {
  std::vector<double> freq_Hz;
  std::vector<std::complex<double>> z_Ns_m;  // Z_loaded − Z_unloaded (or Z_loaded alone)
  std::vector<double> mass_kg;               // Im(Z_f)/ω (0 at DC)
  std::vector<double> damping_Ns_m;          // Re(Z_f)
  std::vector<double> damping_ratio;         // b / (2 m ω) (0 where m ω = 0)
  std::vector<double> coherence;             // min of the loaded and unloaded coherences
};

// `unloaded` may be null (the plate's own impedance already removed, or negligible). Both spectra must
// share one frequency axis (same sample rate and segment).
FingerImpedance finger_impedance(const ImpedanceSpectrum& loaded, const ImpedanceSpectrum* unloaded);

struct MassSpringDamper {
  double m_kg = 0.0;
  double c_Ns_m = 0.0;
  double k_N_m = 0.0;
  double natural_frequency_Hz() const;
  double damping_ratio() const;
  // G2(jω) = X/F
  std::complex<double> compliance_m_N(double f_Hz) const;
};

struct MckFit {
  MassSpringDamper mck;
  std::size_t frequencies_used = 0;
  double band_low_Hz = 0.0, band_high_Hz = 0.0;
  double relative_residual = 0.0;  // ‖fit − data‖ / ‖data‖ over the used bins
  // Standard deviations from the weighted least squares (residual variance × (AᵀA)⁻¹), in the
  // parameters' units; 0 for a fixed stiffness.
  double m_sd_kg = 0.0, c_sd_Ns_m = 0.0, k_sd_N_m = 0.0;
  // Correlation of the m and k estimates: near ±1 the band cannot tell a stiffer spring from a lighter
  // mass (k − mω² barely changes across it); 0 for a fixed stiffness.
  double m_k_correlation = 0.0;
  bool stiffness_fixed = false;
};

// |m_k_correlation| above this: the fit trades k against m and says so.
inline constexpr double kMassStiffnessCorrelationLimit = 0.95;

struct MckFitOptions {
  double band_low_Hz = 0.0;    // 0 = from the first non-DC bin
  double band_high_Hz = 0.0;   // 0 = up to Nyquist
  double min_coherence = 0.9;  // bins below are not used
  // Stiffness held at this value, N/m (e.g. 0: a mass and a damper only); unset: fitted.
  std::optional<double> fixed_stiffness_N_m;
};

// Least squares on Re: k − mω² = Re(F/X) and Im: cω = Im(F/X), with F/X = −ω²/H1(F→A); each bin weighted
// by 1/|F/X| so every frequency counts by its relative error (a sweep's resonance would otherwise be
// ignored next to the stiff high-frequency bins). Throws Error if fewer than 3 bins qualify.
MckFit fit_mass_spring_damper(const TransferEstimate& force_to_accel, const MckFitOptions& options);
// The same fit on a dynamic stiffness F/X = jω·Z already computed per bin (e.g. from Z_f = Z_loaded −
// Z_unloaded); `coherence` gates the bins as above.
MckFit fit_mass_spring_damper(const std::vector<double>& freq_Hz,
                              const std::vector<std::complex<double>>& dynamic_stiffness_N_m,
                              const std::vector<double>& coherence, const MckFitOptions& options);
// The same fit on a finger's impedance Z_f (F/X = jω·Z_f), gated by its coherence.
MckFit fit_mass_spring_damper(const FingerImpedance& finger, const MckFitOptions& options);
MckFit fit_mass_spring_damper(const std::vector<double>& force_N, const std::vector<double>& accel_m_s2,
                              double sample_rate_Hz, const WelchOptions& welch, const MckFitOptions& options);

struct PadTransfer {
  std::vector<double> freq_Hz;
  std::vector<std::complex<double>> g1;  // A_side / A_pad
  std::vector<double> coherence;
  std::vector<char> valid;                       // coherence >= min_coherence (and not DC)
  double band_low_Hz = 0.0, band_high_Hz = 0.0;  // the widest contiguous valid band
};

PadTransfer calibrate_pad_transfer(const std::vector<double>& pad_accel_m_s2,
                                   const std::vector<double>& side_accel_m_s2, double sample_rate_Hz,
                                   const WelchOptions& options, double min_coherence);

// PSD of X_p from the side accelerometer: P_side / (ω⁴·|G1|²), 0 outside the valid bins.
std::vector<double> pad_displacement_psd_from_side(const PadTransfer& g1,
                                                   const std::vector<double>& side_psd);
// PSD of X_p from the tangential force: P_F·|G2|².
std::vector<double> pad_displacement_psd_from_force(const std::vector<double>& freq_Hz,
                                                    const std::vector<double>& force_psd,
                                                    const MassSpringDamper& mck);

// RMS over [low, high) from a one-sided density: sqrt(Σ P·Δf).
double band_rms(const std::vector<double>& freq_Hz, const std::vector<double>& psd, double low_Hz,
                double high_Hz);

}  // namespace tirstrain::signals
