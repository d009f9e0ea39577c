#pragma once
// Command-line value checks whose messages say what is expected (CLI11's own range validators print the
// range's limits as 300-digit numbers).
#include <string>

#include <CLI/CLI.hpp>

namespace tirstrain::cli {

// A value read as T and accepted when ok(value): otherwise "must be <expected>; got <text>".
template <typename T, typename Ok>
CLI::Validator value_check(Ok ok, const std::string& expected, const std::string& name) {
  return CLI::Validator(
      [ok, expected](std::string& text) {
        T value{};
        return CLI::detail::lexical_cast(text, value) && ok(value) ? std::string()
                                                                   : "must be " + expected + "; got " + text;
      },
      name);
}

// A count of samples: 0 or more.
inline const CLI::Validator kSamplesAtLeastZero =
    value_check<long>([](long v) { return v >= 0; }, "a whole number of samples, 0 or more", "SAMPLES>=0");
// An index or count: a whole number, 0 or more.
inline const CLI::Validator kWholeAtLeastZero =
    value_check<long>([](long v) { return v >= 0; }, "a whole number, 0 or more", "INT>=0");
// A frequency: above 0 Hz.
inline const CLI::Validator kPositiveHz =
    value_check<double>([](double v) { return v > 0.0; }, "a frequency above 0 Hz", "HZ>0");
// Any quantity above 0 (a count, a duration, a rate, a length).
inline const CLI::Validator kPositive =
    value_check<double>([](double v) { return v > 0.0; }, "a number above 0", ">0");
// Any quantity of 0 or more.
inline const CLI::Validator kAtLeastZero =
    value_check<double>([](double v) { return v >= 0.0; }, "a number of 0 or more", ">=0");

}  // namespace tirstrain::cli
