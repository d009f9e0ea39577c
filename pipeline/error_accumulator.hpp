#pragma once
// Running error statistics (RMS, largest magnitude, signed mean) for `validate`'s report rows.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "pipeline/validate.hpp"

namespace tirstrain::pipeline {

struct ErrorAccumulator {
  double sum = 0.0, sum2 = 0.0, max_abs = 0.0;
  long n = 0;
  // Non-finite errors are skipped: a quantity a frame does not have is absent, not an error.
  void add(double error) {
    if (!std::isfinite(error)) return;
    sum += error;
    sum2 += error * error;
    max_abs = std::max(max_abs, std::abs(error));
    ++n;
  }
  ErrorStats stats(std::string quantity, std::string reference, std::string mode, std::string unit) const {
    ErrorStats s{std::move(quantity), std::move(reference), std::move(mode), std::move(unit)};
    s.samples = n;
    if (n > 0) {
      s.rms = std::sqrt(sum2 / static_cast<double>(n));
      s.mean = sum / static_cast<double>(n);
      s.max_abs = max_abs;
    } else {
      s.rms = s.mean = s.max_abs = std::numeric_limits<double>::quiet_NaN();
    }
    return s;
  }
};

}  // namespace tirstrain::pipeline
