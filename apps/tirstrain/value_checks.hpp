#pragma once
// Command-line value checks whose messages say what is expected (CLI11's own range validators print the
// range's limits as 300-digit numbers).
#include <string>

#include <CLI/CLI.hpp>

namespace tirstrain::cli {

// A count of samples: 0 or more.
inline const CLI::Validator kSamplesAtLeastZero(
    [](std::string& text) {
      long value = 0;
      return CLI::detail::lexical_cast(text, value) && value >= 0
                 ? std::string()
                 : "must be a whole number of samples, 0 or more; got " + text;
    },
    "SAMPLES>=0");
// An index or count: a whole number, 0 or more.
inline const CLI::Validator kWholeAtLeastZero(
    [](std::string& text) {
      long value = 0;
      return CLI::detail::lexical_cast(text, value) && value >= 0
                 ? std::string()
                 : "must be a whole number, 0 or more; got " + text;
    },
    "INT>=0");
// A frequency: above 0 Hz.
inline const CLI::Validator kPositiveHz(
    [](std::string& text) {
      double value = 0.0;
      return CLI::detail::lexical_cast(text, value) && value > 0.0
                 ? std::string()
                 : "must be a frequency above 0 Hz; got " + text;
    },
    "HZ>0");

// Any quantity above 0 (a count, a duration, a rate, a length).
inline const CLI::Validator kPositive(
    [](std::string& text) {
      double value = 0.0;
      return CLI::detail::lexical_cast(text, value) && value > 0.0 ? std::string()
                                                                   : "must be a number above 0; got " + text;
    },
    ">0");
// Any quantity of 0 or more.
inline const CLI::Validator kAtLeastZero(
    [](std::string& text) {
      double value = 0.0;
      return CLI::detail::lexical_cast(text, value) && value >= 0.0
                 ? std::string()
                 : "must be a number of 0 or more; got " + text;
    },
    ">=0");

}  // namespace tirstrain::cli
