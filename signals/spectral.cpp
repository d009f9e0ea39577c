#include "signals/spectral.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>

#include <unsupported/Eigen/FFT>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

using cplx = std::complex<double>;

struct Segmentation {
  std::size_t segment = 0;
  std::size_t step = 0;
  std::size_t count = 0;
};

Segmentation plan(std::size_t n, double sample_rate_Hz, const WelchOptions& options) {
  if (!(sample_rate_Hz > 0.0) || !std::isfinite(sample_rate_Hz))
    throw Error("sample rate must be positive", {.key = "sample_rate_Hz"});
  const std::size_t seg = options.segment;
  if (seg < 2) throw Error("segment must be at least 2 samples", {.key = "segment"});
  if (seg > n)
    throw Error("segment of " + std::to_string(seg) + " samples is longer than the signal (" +
                    std::to_string(n) + " samples)",
                {.key = "segment"});
  const std::size_t overlap = options.overlap.value_or(seg / 2);
  if (overlap >= seg) throw Error("overlap must be smaller than the segment", {.key = "overlap"});
  Segmentation s;
  s.segment = seg;
  s.step = seg - overlap;
  s.count = (n - overlap) / s.step;
  return s;
}

void detrend_segment(std::vector<double>& seg, Detrend mode) {
  const std::size_t n = seg.size();
  if (mode == Detrend::none) return;
  if (mode == Detrend::constant) {
    double mean = 0.0;
    for (double v : seg) mean += v;
    mean /= static_cast<double>(n);
    for (double& v : seg) v -= mean;
    return;
  }
  // Least-squares line against a centred abscissa, so slope and intercept decouple.
  const double centre = 0.5 * static_cast<double>(n - 1);
  double sum_y = 0.0, sum_ty = 0.0, sum_tt = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) - centre;
    sum_y += seg[i];
    sum_ty += t * seg[i];
    sum_tt += t * t;
  }
  const double mean = sum_y / static_cast<double>(n);
  const double slope = sum_tt > 0.0 ? sum_ty / sum_tt : 0.0;
  for (std::size_t i = 0; i < n; ++i) seg[i] -= mean + slope * (static_cast<double>(i) - centre);
}

// Reused per-call FFT state: window, scratch segment, output bins.
class SegmentTransformer {
 public:
  SegmentTransformer(std::size_t segment, Detrend detrend)
      : window_(hann_periodic(segment)), scratch_(segment), detrend_(detrend) {
    fft_.SetFlag(Eigen::FFT<double>::HalfSpectrum);
    for (double w : window_) window_power_ += w * w;
  }
  const std::vector<cplx>& transform(const std::vector<double>& x, std::size_t start) {
    std::copy(x.begin() + static_cast<std::ptrdiff_t>(start),
              x.begin() + static_cast<std::ptrdiff_t>(start + scratch_.size()), scratch_.begin());
    detrend_segment(scratch_, detrend_);
    for (std::size_t i = 0; i < scratch_.size(); ++i) scratch_[i] *= window_[i];
    fft_.fwd(bins_, scratch_);
    return bins_;
  }
  double window_power() const { return window_power_; }

 private:
  Eigen::FFT<double> fft_;
  std::vector<double> window_;
  std::vector<double> scratch_;
  std::vector<cplx> bins_;
  Detrend detrend_;
  double window_power_ = 0.0;
};

// Density scale, averaging, and the one-sided doubling (not DC, not the Nyquist bin of an even nfft).
std::vector<double> onesided_scale(std::size_t nfft, std::size_t bins, double sample_rate_Hz,
                                   double window_power, std::size_t segments) {
  std::vector<double> scale(bins, 1.0 / (sample_rate_Hz * window_power * static_cast<double>(segments)));
  const std::size_t last_doubled = nfft % 2 == 0 ? bins - 1 : bins;
  for (std::size_t k = 1; k < last_doubled; ++k) scale[k] *= 2.0;
  return scale;
}

}  // namespace

std::vector<double> hann_periodic(std::size_t n) {
  std::vector<double> w(n);
  for (std::size_t i = 0; i < n; ++i)
    w[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n));
  return w;
}

std::vector<double> rfft_frequencies(std::size_t nfft, double sample_rate_Hz) {
  std::vector<double> f(nfft / 2 + 1);
  for (std::size_t k = 0; k < f.size(); ++k)
    f[k] = static_cast<double>(k) * sample_rate_Hz / static_cast<double>(nfft);
  return f;
}

std::vector<std::complex<double>> rfft(const std::vector<double>& x) {
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::vector<cplx> out;
  std::vector<double> in = x;
  fft.fwd(out, in);
  return out;
}

namespace {

// A spectrum sums squared samples: one beyond the square root of a double's range would give infinities
// that look like measured power. Said instead, with the largest sample.
void check_power_range(const std::vector<double>& x, const char* which) {
  const double limit = std::sqrt(std::numeric_limits<double>::max()) * 1e-3;
  const auto largest =
      std::max_element(x.begin(), x.end(), [](double a, double b) { return std::abs(a) < std::abs(b); });
  if (largest != x.end() && !(std::abs(*largest) < limit)) {
    char value[32];
    std::snprintf(value, sizeof value, "%g", *largest);
    throw Error(std::string("the ") + which + " reaches " + value +
                    ": its power would overflow a double; rescale it (e.g. to SI units)",
                {});
  }
}

}  // namespace

PowerSpectrum welch(const std::vector<double>& x, double sample_rate_Hz, const WelchOptions& options) {
  check_power_range(x, "signal");
  const Segmentation s = plan(x.size(), sample_rate_Hz, options);
  SegmentTransformer tr(s.segment, options.detrend);
  PowerSpectrum out;
  out.freq_Hz = rfft_frequencies(s.segment, sample_rate_Hz);
  out.psd.assign(out.freq_Hz.size(), 0.0);
  out.segments = s.count;
  for (std::size_t k = 0; k < s.count; ++k) {
    const auto& bins = tr.transform(x, k * s.step);
    for (std::size_t i = 0; i < out.psd.size(); ++i) out.psd[i] += std::norm(bins[i]);
  }
  const auto scale = onesided_scale(s.segment, out.psd.size(), sample_rate_Hz, tr.window_power(), s.count);
  for (std::size_t i = 0; i < out.psd.size(); ++i) out.psd[i] *= scale[i];
  return out;
}

TransferEstimate transfer_estimate(const std::vector<double>& x, const std::vector<double>& y,
                                   double sample_rate_Hz, const WelchOptions& options) {
  if (x.size() != y.size())
    throw Error("input and output have different lengths (" + std::to_string(x.size()) + " and " +
                    std::to_string(y.size()) + " samples)",
                {});
  check_power_range(x, "input");
  check_power_range(y, "output");
  const Segmentation s = plan(x.size(), sample_rate_Hz, options);
  SegmentTransformer tx(s.segment, options.detrend), ty(s.segment, options.detrend);
  TransferEstimate out;
  out.freq_Hz = rfft_frequencies(s.segment, sample_rate_Hz);
  const std::size_t nb = out.freq_Hz.size();
  out.pxx.assign(nb, 0.0);
  out.pyy.assign(nb, 0.0);
  out.pxy.assign(nb, cplx(0.0, 0.0));
  out.segments = s.count;
  for (std::size_t k = 0; k < s.count; ++k) {
    const auto& bx = tx.transform(x, k * s.step);
    const auto& by = ty.transform(y, k * s.step);
    for (std::size_t i = 0; i < nb; ++i) {
      out.pxx[i] += std::norm(bx[i]);
      out.pyy[i] += std::norm(by[i]);
      out.pxy[i] += std::conj(bx[i]) * by[i];
    }
  }
  const auto scale = onesided_scale(s.segment, nb, sample_rate_Hz, tx.window_power(), s.count);
  out.h1.assign(nb, cplx(0.0, 0.0));
  out.coherence.assign(nb, 0.0);
  for (std::size_t i = 0; i < nb; ++i) {
    out.pxx[i] *= scale[i];
    out.pyy[i] *= scale[i];
    out.pxy[i] *= scale[i];
    if (out.pxx[i] > 0.0) out.h1[i] = out.pxy[i] / out.pxx[i];
    const double denom = out.pxx[i] * out.pyy[i];
    // Zero power in either channel leaves coherence undefined; reporting 0 keeps every output finite and
    // marks the bin as unusable.
    if (denom > 0.0) out.coherence[i] = std::min(1.0, std::norm(out.pxy[i]) / denom);
  }
  return out;
}

CrossSpectrum csd(const std::vector<double>& x, const std::vector<double>& y, double sample_rate_Hz,
                  const WelchOptions& options) {
  TransferEstimate t = transfer_estimate(x, y, sample_rate_Hz, options);
  return {std::move(t.freq_Hz), std::move(t.pxy), t.segments};
}

std::vector<Peak> find_peaks(const std::vector<double>& x, const PeakOptions& options) {
  std::vector<std::size_t> candidates;
  const std::size_t n = x.size();
  if (n >= 3) {
    std::size_t i = 1;
    const std::size_t i_max = n - 1;
    while (i < i_max) {
      if (x[i - 1] < x[i]) {
        std::size_t ahead = i + 1;
        while (ahead < i_max && x[ahead] == x[i]) ++ahead;
        if (x[ahead] < x[i]) {
          candidates.push_back((i + ahead - 1) / 2);
          i = ahead;
        }
      }
      ++i;
    }
  }
  if (options.min_height) {
    std::erase_if(candidates, [&](std::size_t p) { return x[p] < *options.min_height; });
  }
  if (options.min_distance > 1 && candidates.size() > 1) {
    std::vector<std::size_t> order(candidates.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return x[candidates[a]] > x[candidates[b]]; });
    std::vector<char> keep(candidates.size(), 1);
    for (std::size_t k : order) {
      if (!keep[k]) continue;
      for (std::size_t j = k; j-- > 0 && candidates[k] - candidates[j] < options.min_distance;) keep[j] = 0;
      for (std::size_t j = k + 1;
           j < candidates.size() && candidates[j] - candidates[k] < options.min_distance; ++j)
        keep[j] = 0;
    }
    std::vector<std::size_t> kept;
    for (std::size_t k = 0; k < candidates.size(); ++k)
      if (keep[k]) kept.push_back(candidates[k]);
    candidates = std::move(kept);
  }
  std::vector<Peak> peaks;
  for (std::size_t p : candidates) {
    Peak peak;
    peak.index = p;
    peak.value = x[p];
    double left_min = x[p];
    peak.left_base = p;
    for (std::size_t i = p + 1; i-- > 0 && x[i] <= x[p];) {
      if (x[i] < left_min) {
        left_min = x[i];
        peak.left_base = i;
      }
    }
    double right_min = x[p];
    peak.right_base = p;
    for (std::size_t i = p; i < n && x[i] <= x[p]; ++i) {
      if (x[i] < right_min) {
        right_min = x[i];
        peak.right_base = i;
      }
    }
    peak.prominence = x[p] - std::max(left_min, right_min);
    if (peak.prominence >= options.min_prominence) peaks.push_back(peak);
  }
  return peaks;
}

double parabolic_peak_index(const std::vector<double>& x, std::size_t index) {
  if (index == 0 || index + 1 >= x.size()) return static_cast<double>(index);
  const double left = x[index - 1], mid = x[index], right = x[index + 1];
  const double denom = left - 2.0 * mid + right;
  if (denom == 0.0) return static_cast<double>(index);
  return static_cast<double>(index) + 0.5 * (left - right) / denom;
}

}  // namespace tirstrain::signals
