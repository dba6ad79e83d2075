#include "core/cone.hpp"

#include <array>
#include <utility>

namespace conesim::core {

namespace {
constexpr std::array<std::pair<ConeClass, std::string_view>, 5> kNames{{
    {ConeClass::kBlue, "blue"},
    {ConeClass::kYellow, "yellow"},
    {ConeClass::kOrangeSmall, "orange_small"},
    {ConeClass::kOrangeBig, "orange_big"},
    {ConeClass::kUnknown, "unknown"},
}};
}  // namespace

std::string_view to_string(ConeClass c) {
  for (const auto& [cls, name] : kNames)
    if (cls == c) return name;
  return "unknown";
}

std::optional<ConeClass> cone_class_from_string(std::string_view name) {
  for (const auto& [cls, n] : kNames)
    if (n == name) return cls;
  return std::nullopt;
}

ConeSize cone_size(ConeClass c) {
  if (c == ConeClass::kOrangeBig) return {0.285, 0.505};
  return {0.228, 0.325};
}

}  // namespace conesim::core
