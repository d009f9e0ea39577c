#include "core/error.hpp"

namespace tirstrain {

std::string format_error(const std::string& message, const ErrorContext& context) {
  std::string out;
  if (!context.file.empty()) out += context.file + ": ";
  if (context.frame) out += "frame " + std::to_string(*context.frame) + ": ";
  if (context.row) out += "row " + std::to_string(*context.row) + ": ";
  if (!context.column.empty()) out += "column '" + context.column + "': ";
  if (!context.key.empty()) out += "'" + context.key + "': ";
  return out + message;
}

Error::Error(const std::string& message, ErrorContext context)
    : std::runtime_error(format_error(message, context)), message_(message), context_(std::move(context)) {}

}  // namespace tirstrain
