#pragma once
// The one project error type: a user-facing message with where it happened (file, frame, row, column, key).
#include <optional>
#include <stdexcept>
#include <string>

namespace tirstrain {

struct ErrorContext {
  std::string file;           // path of the offending input, if any
  std::optional<long> frame;  // frame index (0-based) in a sequence
  std::optional<long> row;    // 1-based line number in a text file (header is row 1)
  std::string column;         // column / dataset / channel name
  std::string key;            // configuration key or command-line option, e.g. "tissue.E_Pa" or "--poisson"
};

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message, ErrorContext context = {});
  const ErrorContext& context() const noexcept { return context_; }
  // The bare message without the location prefix.
  const std::string& message() const noexcept { return message_; }

 private:
  std::string message_;
  ErrorContext context_;
};

// Runs fn(). An Error it throws that names no file (a library error that knows the parameter but not where
// the value came from) is thrown again with its context completed by `complete(ErrorContext&)`.
template <typename Fn, typename Complete>
auto with_error_context(Fn&& fn, Complete&& complete) -> decltype(fn()) {
  try {
    return fn();
  } catch (const Error& e) {
    if (!e.context().file.empty()) throw;
    ErrorContext context = e.context();
    complete(context);
    throw Error(e.message(), context);
  }
}

// "file: frame 3: row 12: column 'normal_N': key 'x': message" with empty parts left out.
std::string format_error(const std::string& message, const ErrorContext& context);

}  // namespace tirstrain
