#include "core/error.hpp"

namespace conesim::core {

namespace {
std::string at_line(const std::string& file, int line, const std::string& message) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + message;
  return file + ": " + message;
}
}  // namespace

InputError::InputError(const std::string& file, int line, const std::string& message)
    : std::runtime_error(at_line(file, line, message)), file_(file), line_(line) {}

InputError::InputError(const std::string& file, const std::string& key, const std::string& message)
    : std::runtime_error(file + ": " + key + ": " + message), file_(file), key_(key) {}

}  // namespace conesim::core
