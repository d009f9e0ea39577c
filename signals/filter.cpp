#include "signals/filter.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

using cplx = std::complex<double>;

struct Zpk {
  std::vector<cplx> zeros;
  std::vector<cplx> poles;
  double gain = 1.0;
};

void validate(const ButterworthSpec& spec) {
  if (spec.order < 1 || spec.order > 64)
    throw Error("Butterworth order must be between 1 and 64, got " + std::to_string(spec.order),
                {.key = "order"});
  if (!(spec.sample_rate_Hz > 0.0) || !std::isfinite(spec.sample_rate_Hz))
    throw Error("sample rate must be positive", {.key = "sample_rate_Hz"});
  const double nyquist_Hz = 0.5 * spec.sample_rate_Hz;
  auto check = [&](double f_Hz, const char* key) {
    if (!(f_Hz > 0.0 && f_Hz < nyquist_Hz))
      throw Error("cutoff " + std::to_string(f_Hz) +
                      " Hz must lie strictly between 0 and the Nyquist frequency " +
                      std::to_string(nyquist_Hz) + " Hz",
                  {.key = key});
  };
  check(spec.cutoff_Hz, "cutoff_Hz");
  if (spec.type == FilterType::bandpass) {
    check(spec.cutoff2_Hz, "cutoff2_Hz");
    if (!(spec.cutoff_Hz < spec.cutoff2_Hz))
      throw Error("band-pass lower edge must be below the upper edge", {.key = "cutoff_Hz"});
  }
}

// Analog Butterworth prototype: N poles evenly spaced on the left half of the unit circle, unit DC gain.
Zpk analog_prototype(int order) {
  Zpk zpk;
  for (int k = 0; k < order; ++k) {
    const double angle = std::numbers::pi * (2.0 * k + order + 1) / (2.0 * order);
    // The middle pole of an odd order is exactly -1; cos/sin would leave a 1e-16 imaginary part that
    // would break the conjugate pairing below.
    if (2 * k + 1 == order)
      zpk.poles.emplace_back(-1.0, 0.0);
    else
      zpk.poles.emplace_back(std::cos(angle), std::sin(angle));
  }
  return zpk;
}

cplx product_of(const std::vector<cplx>& values, cplx offset, double sign) {
  cplx out(1.0, 0.0);
  for (const cplx& v : values) out *= offset + sign * v;
  return out;
}

Zpk design_digital(const ButterworthSpec& spec) {
  validate(spec);
  const double fs = spec.sample_rate_Hz;
  // Pre-warping makes the -3 dB points land exactly on the requested digital frequencies.
  auto warp = [fs](double f_Hz) { return 2.0 * fs * std::tan(std::numbers::pi * f_Hz / fs); };
  Zpk proto = analog_prototype(spec.order);
  Zpk analog;
  const std::size_t degree = proto.poles.size() - proto.zeros.size();
  if (spec.type == FilterType::lowpass) {
    const double w = warp(spec.cutoff_Hz);
    for (const cplx& p : proto.poles) analog.poles.push_back(w * p);
    analog.gain = proto.gain * std::pow(w, static_cast<double>(degree));
  } else if (spec.type == FilterType::highpass) {
    const double w = warp(spec.cutoff_Hz);
    for (const cplx& p : proto.poles) analog.poles.push_back(w / p);
    analog.zeros.assign(degree, cplx(0.0, 0.0));
    analog.gain =
        proto.gain * (product_of(proto.zeros, 0.0, -1.0) / product_of(proto.poles, 0.0, -1.0)).real();
  } else {
    const double w1 = warp(spec.cutoff_Hz);
    const double w2 = warp(spec.cutoff2_Hz);
    const double bw = w2 - w1;
    const double w0_sq = w1 * w2;
    for (const cplx& p : proto.poles) {
      const cplx half = 0.5 * p * bw;
      const cplx root = std::sqrt(half * half - w0_sq);
      analog.poles.push_back(half + root);
      analog.poles.push_back(half - root);
    }
    analog.zeros.assign(degree, cplx(0.0, 0.0));
    analog.gain = proto.gain * std::pow(bw, static_cast<double>(degree));
  }

  // Bilinear transform s = 2fs (z-1)/(z+1); zeros at s = ∞ land on z = -1.
  const double fs2 = 2.0 * fs;
  Zpk digital;
  for (const cplx& z : analog.zeros) digital.zeros.push_back((fs2 + z) / (fs2 - z));
  for (const cplx& p : analog.poles) digital.poles.push_back((fs2 + p) / (fs2 - p));
  digital.zeros.resize(digital.poles.size(), cplx(-1.0, 0.0));
  digital.gain =
      analog.gain * (product_of(analog.zeros, fs2, -1.0) / product_of(analog.poles, fs2, -1.0)).real();
  return digital;
}

// Splits roots into conjugate pairs (one representative with positive imaginary part) and real roots.
void split_roots(const std::vector<cplx>& roots, std::vector<cplx>& pairs, std::vector<double>& reals) {
  for (const cplx& r : roots) {
    const double tol = 1e-10 * std::max(1.0, std::abs(r));
    if (std::abs(r.imag()) <= tol)
      reals.push_back(r.real());
    else if (r.imag() > 0.0)
      pairs.push_back(r);
  }
}

SosFilter zpk_to_sos(const Zpk& zpk) {
  std::vector<cplx> pole_pairs, zero_pairs;
  std::vector<double> real_poles, real_zeros;
  split_roots(zpk.poles, pole_pairs, real_poles);
  split_roots(zpk.zeros, zero_pairs, real_zeros);

  struct PoleGroup {
    double a1, a2, radius;
    int count;
  };
  std::vector<PoleGroup> groups;
  for (const cplx& p : pole_pairs) groups.push_back({-2.0 * p.real(), std::norm(p), std::abs(p), 2});
  std::sort(real_poles.begin(), real_poles.end());
  for (std::size_t i = 0; i + 1 < real_poles.size(); i += 2) {
    const double p1 = real_poles[i], p2 = real_poles[i + 1];
    groups.push_back({-(p1 + p2), p1 * p2, std::max(std::abs(p1), std::abs(p2)), 2});
  }
  if (real_poles.size() % 2 == 1) {
    const double p = real_poles.back();
    groups.push_back({-p, 0.0, std::abs(p), 1});
  }
  // Poles nearest the unit circle last, as SciPy orders them, so the sharpest resonance sees a signal that
  // the earlier sections have already shaped.
  std::stable_sort(groups.begin(), groups.end(),
                   [](const PoleGroup& a, const PoleGroup& b) { return a.radius < b.radius; });

  // Zero factors: conjugate pairs first, then real zeros paired smallest with largest, which gives a
  // band-pass the well-scaled (1 - z⁻²) sections.
  struct ZeroFactor {
    double b1, b2;
    int count;
  };
  std::vector<ZeroFactor> zero_factors;
  for (const cplx& z : zero_pairs) zero_factors.push_back({-2.0 * z.real(), std::norm(z), 2});
  std::sort(real_zeros.begin(), real_zeros.end());
  std::vector<double> single_zeros;
  std::size_t lo = 0, hi = real_zeros.size();
  while (hi - lo >= 2) {
    const double z1 = real_zeros[lo++], z2 = real_zeros[--hi];
    zero_factors.push_back({-(z1 + z2), z1 * z2, 2});
  }
  if (hi - lo == 1) single_zeros.push_back(real_zeros[lo]);

  SosFilter filter;
  filter.order = static_cast<int>(zpk.poles.size());
  std::size_t next_pair = 0;
  for (const PoleGroup& g : groups) {
    Biquad s;
    s.a1 = g.a1;
    s.a2 = g.a2;
    if (g.count == 1 && !single_zeros.empty()) {
      s.b1 = -single_zeros.back();
      single_zeros.pop_back();
    } else if (next_pair < zero_factors.size()) {
      s.b1 = zero_factors[next_pair].b1;
      s.b2 = zero_factors[next_pair].b2;
      ++next_pair;
    } else if (!single_zeros.empty()) {
      s.b1 = -single_zeros.back();
      single_zeros.pop_back();
    }
    filter.sections.push_back(s);
  }
  if (!filter.sections.empty()) {
    filter.sections.front().b0 *= zpk.gain;
    filter.sections.front().b1 *= zpk.gain;
    filter.sections.front().b2 *= zpk.gain;
  }
  return filter;
}

std::vector<double> real_poly(const std::vector<cplx>& roots) {
  std::vector<cplx> c{cplx(1.0, 0.0)};
  for (const cplx& r : roots) {
    c.push_back(cplx(0.0, 0.0));
    for (std::size_t i = c.size() - 1; i > 0; --i) c[i] -= r * c[i - 1];
  }
  std::vector<double> out(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) out[i] = c[i].real();
  return out;
}

cplx eval_section(const Biquad& s, cplx zinv) {
  return (s.b0 + zinv * (s.b1 + zinv * s.b2)) / (1.0 + zinv * (s.a1 + zinv * s.a2));
}

// Steady-state DF2T states of one biquad for a constant unit input.
void biquad_zi(const Biquad& s, double& z0, double& z1) {
  const double gain = (s.b0 + s.b1 + s.b2) / (1.0 + s.a1 + s.a2);
  z1 = s.b2 - s.a2 * gain;
  z0 = s.b1 - s.a1 * gain + z1;
}

std::vector<double> odd_extend(const std::vector<double>& x, std::size_t padlen) {
  const std::size_t n = x.size();
  std::vector<double> ext(n + 2 * padlen);
  for (std::size_t i = 0; i < padlen; ++i) ext[i] = 2.0 * x[0] - x[padlen - i];
  std::copy(x.begin(), x.end(), ext.begin() + static_cast<std::ptrdiff_t>(padlen));
  for (std::size_t i = 0; i < padlen; ++i) ext[padlen + n + i] = 2.0 * x[n - 1] - x[n - 2 - i];
  return ext;
}

void check_length(std::size_t n, std::size_t padlen) {
  if (n <= padlen)
    throw Error("signal has " + std::to_string(n) +
                " samples; zero-phase filtering needs more than padlen = " + std::to_string(padlen) +
                " (3 x (filter order + 1)) samples");
}

template <typename Filter, typename Run, typename Zi>
std::vector<double> filtfilt_impl(const Filter& filter, const std::vector<double>& x, std::size_t padlen,
                                  Run run, Zi zi_fn) {
  check_length(x.size(), padlen);
  const std::vector<double> zi = zi_fn(filter);
  std::vector<double> ext = odd_extend(x, padlen);
  std::vector<double> state(zi.size());
  for (std::size_t i = 0; i < zi.size(); ++i) state[i] = zi[i] * ext.front();
  std::vector<double> y = run(filter, ext, &state);
  std::reverse(y.begin(), y.end());
  for (std::size_t i = 0; i < zi.size(); ++i) state[i] = zi[i] * y.front();
  y = run(filter, y, &state);
  std::reverse(y.begin(), y.end());
  return std::vector<double>(y.begin() + static_cast<std::ptrdiff_t>(padlen),
                             y.end() - static_cast<std::ptrdiff_t>(padlen));
}

}  // namespace

SosFilter butterworth_sos(const ButterworthSpec& spec) {
  return zpk_to_sos(design_digital(spec));
}

TransferFunction butterworth_ba(const ButterworthSpec& spec) {
  const Zpk zpk = design_digital(spec);
  TransferFunction tf;
  tf.b = real_poly(zpk.zeros);
  for (double& v : tf.b) v *= zpk.gain;
  tf.a = real_poly(zpk.poles);
  return tf;
}

std::complex<double> frequency_response(const SosFilter& filter, double f_Hz, double sample_rate_Hz) {
  const cplx zinv = std::polar(1.0, -2.0 * std::numbers::pi * f_Hz / sample_rate_Hz);
  cplx h(1.0, 0.0);
  for (const Biquad& s : filter.sections) h *= eval_section(s, zinv);
  return h;
}

std::complex<double> frequency_response(const TransferFunction& filter, double f_Hz, double sample_rate_Hz) {
  const cplx zinv = std::polar(1.0, -2.0 * std::numbers::pi * f_Hz / sample_rate_Hz);
  auto horner = [zinv](const std::vector<double>& c) {
    cplx acc(0.0, 0.0);
    for (std::size_t i = c.size(); i-- > 0;) acc = acc * zinv + c[i];
    return acc;
  };
  return horner(filter.b) / horner(filter.a);
}

double butterworth_power_response(const ButterworthSpec& spec, double f_Hz) {
  validate(spec);
  const double fs = spec.sample_rate_Hz;
  auto warp = [fs](double f) { return std::tan(std::numbers::pi * f / fs); };
  const double w = warp(f_Hz);
  const double two_n = 2.0 * spec.order;
  double ratio = 0.0;
  switch (spec.type) {
    case FilterType::lowpass:
      ratio = w / warp(spec.cutoff_Hz);
      break;
    case FilterType::highpass:
      if (w == 0.0) return 0.0;
      ratio = warp(spec.cutoff_Hz) / w;
      break;
    case FilterType::bandpass: {
      if (w == 0.0) return 0.0;
      const double w1 = warp(spec.cutoff_Hz), w2 = warp(spec.cutoff2_Hz);
      ratio = (w * w - w1 * w2) / (w * (w2 - w1));
      break;
    }
  }
  return 1.0 / (1.0 + std::pow(std::abs(ratio), two_n));
}

std::vector<double> sosfilt(const SosFilter& filter, const std::vector<double>& x,
                            const std::vector<double>* initial) {
  if (initial && initial->size() != 2 * filter.sections.size())
    throw Error("internal: sosfilt initial state needs 2 values per section");
  std::vector<double> y = x;
  for (std::size_t k = 0; k < filter.sections.size(); ++k) {
    const Biquad& s = filter.sections[k];
    double z0 = initial ? (*initial)[2 * k] : 0.0;
    double z1 = initial ? (*initial)[2 * k + 1] : 0.0;
    for (double& v : y) {
      const double in = v;
      const double out = s.b0 * in + z0;
      z0 = s.b1 * in - s.a1 * out + z1;
      z1 = s.b2 * in - s.a2 * out;
      v = out;
    }
  }
  return y;
}

std::vector<double> lfilter(const TransferFunction& filter, const std::vector<double>& x,
                            const std::vector<double>* initial) {
  if (filter.a.empty() || filter.a[0] == 0.0) throw Error("internal: lfilter needs a[0] != 0");
  const std::size_t n = std::max(filter.a.size(), filter.b.size());
  std::vector<double> b(n, 0.0), a(n, 0.0);
  for (std::size_t i = 0; i < filter.b.size(); ++i) b[i] = filter.b[i] / filter.a[0];
  for (std::size_t i = 0; i < filter.a.size(); ++i) a[i] = filter.a[i] / filter.a[0];
  std::vector<double> z(n - 1, 0.0);
  if (initial) {
    if (initial->size() != n - 1) throw Error("internal: lfilter initial state has the wrong size");
    z = *initial;
  }
  std::vector<double> y(x.size());
  for (std::size_t t = 0; t < x.size(); ++t) {
    const double out = b[0] * x[t] + (n > 1 ? z[0] : 0.0);
    for (std::size_t i = 0; i + 1 < n - 1; ++i) z[i] = b[i + 1] * x[t] - a[i + 1] * out + z[i + 1];
    if (n > 1) z[n - 2] = b[n - 1] * x[t] - a[n - 1] * out;
    y[t] = out;
  }
  return y;
}

std::vector<double> sosfilt_zi(const SosFilter& filter) {
  std::vector<double> zi(2 * filter.sections.size());
  double scale = 1.0;
  for (std::size_t k = 0; k < filter.sections.size(); ++k) {
    const Biquad& s = filter.sections[k];
    double z0 = 0.0, z1 = 0.0;
    biquad_zi(s, z0, z1);
    zi[2 * k] = scale * z0;
    zi[2 * k + 1] = scale * z1;
    scale *= (s.b0 + s.b1 + s.b2) / (1.0 + s.a1 + s.a2);
  }
  return zi;
}

std::vector<double> lfilter_zi(const TransferFunction& filter) {
  const std::size_t n = std::max(filter.a.size(), filter.b.size());
  std::vector<double> b(n, 0.0), a(n, 0.0);
  for (std::size_t i = 0; i < filter.b.size(); ++i) b[i] = filter.b[i] / filter.a[0];
  for (std::size_t i = 0; i < filter.a.size(); ++i) a[i] = filter.a[i] / filter.a[0];
  double sum_b = 0.0, sum_a = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sum_b += b[i];
    sum_a += a[i];
  }
  const double gain = sum_b / sum_a;
  std::vector<double> zi(n - 1, 0.0);
  double acc = 0.0;
  for (std::size_t i = n - 1; i >= 1; --i) {
    acc += b[i] - a[i] * gain;
    zi[i - 1] = acc;
  }
  return zi;
}

std::size_t default_padlen(const SosFilter& filter) {
  std::size_t zero_b2 = 0, zero_a2 = 0;
  for (const Biquad& s : filter.sections) {
    zero_b2 += s.b2 == 0.0;
    zero_a2 += s.a2 == 0.0;
  }
  const std::size_t ntaps = 2 * filter.sections.size() + 1 - std::min(zero_b2, zero_a2);
  return 3 * ntaps;
}

std::size_t default_padlen(const TransferFunction& filter) {
  return 3 * std::max(filter.a.size(), filter.b.size());
}

std::vector<double> filtfilt(const SosFilter& filter, const std::vector<double>& x) {
  return filtfilt_impl(
      filter, x, default_padlen(filter),
      [](const SosFilter& f, const std::vector<double>& v, const std::vector<double>* s) {
        return sosfilt(f, v, s);
      },
      [](const SosFilter& f) { return sosfilt_zi(f); });
}

std::vector<double> filtfilt(const TransferFunction& filter, const std::vector<double>& x) {
  return filtfilt_impl(
      filter, x, default_padlen(filter),
      [](const TransferFunction& f, const std::vector<double>& v, const std::vector<double>* s) {
        return lfilter(f, v, s);
      },
      [](const TransferFunction& f) { return lfilter_zi(f); });
}

std::vector<double> butterworth_filtfilt(const std::vector<double>& x, const ButterworthSpec& spec) {
  return filtfilt(butterworth_sos(spec), x);
}

}  // namespace tirstrain::signals
