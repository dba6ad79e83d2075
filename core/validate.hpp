#pragma once
// The one check behind every config struct's validate(): a finite number within its range.

#include <cmath>
#include <sstream>
#include <string>

namespace conesim::core {

/// Empty when v is finite and within [lo, hi]; otherwise "key: expected a number in [lo, hi],
/// got v", the message every validate() returns for its first bad key.
inline std::string check_range(const std::string& key, double v, double lo, double hi) {
  if (std::isfinite(v) && v >= lo && v <= hi) return {};
  std::ostringstream s;
  s << key << ": expected a number in [" << lo << ", " << hi << "], got " << v;
  return s.str();
}

}  // namespace conesim::core
