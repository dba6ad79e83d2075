#include "core/clutter.hpp"

namespace conesim::core {

namespace {

// the names in enum order
constexpr std::array<std::string_view, kClutterClassCount> kNames = {
    "barrier", "fence", "tyre_stack", "tent", "person", "spare_cone", "lying_cone", "grass_edge"};

}  // namespace

std::string_view to_string(ClutterClass c) {
  const auto k = static_cast<size_t>(c);
  return k < kNames.size() ? kNames[k] : "unknown";
}

}  // namespace conesim::core
