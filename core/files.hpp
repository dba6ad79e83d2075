#pragma once
// Questions about a path named in user input that never throw. std::filesystem's plain
// is_regular_file/exists/is_directory throw on a name the OS refuses (too long, a bad
// component), and such a name is a user's mistake, to be reported as "no such file", not a crash.

#include <filesystem>
#include <system_error>

namespace conesim::core {

/// true when `p` names a regular file (or a link to one); false for any error
inline bool is_file(const std::filesystem::path& p) noexcept {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec);
}

/// true when `p` names a folder; false for any error
inline bool is_folder(const std::filesystem::path& p) noexcept {
  std::error_code ec;
  return std::filesystem::is_directory(p, ec);
}

/// true when something is at `p`; false for any error
inline bool path_exists(const std::filesystem::path& p) noexcept {
  std::error_code ec;
  return std::filesystem::exists(p, ec);
}

}  // namespace conesim::core
