#pragma once
// Errors for bad input: each names the file, the line or key, and what was expected.

#include <stdexcept>
#include <string>

namespace conesim::core {

/// Raised when an input file or parameter cannot be used. what() reads
/// "file:line: message" (or "file: key: message" when there is no line).
class InputError : public std::runtime_error {
 public:
  /// An error at a line of a file (line 0: the file as a whole).
  InputError(const std::string& file, int line, const std::string& message);
  /// An error at a key of a structured file or of a parameter set.
  InputError(const std::string& file, const std::string& key, const std::string& message);

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& key() const { return key_; }

 private:
  std::string file_;
  int line_ = 0;
  std::string key_;
};

}  // namespace conesim::core
