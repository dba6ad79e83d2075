#pragma once
// Cone classes as the FSG rules define them, and their names in conesim's own files.

#include <optional>
#include <string>
#include <string_view>

namespace conesim::core {

/// The class of a track cone. Blue marks the left boundary, yellow the right one.
enum class ConeClass { kBlue, kYellow, kOrangeSmall, kOrangeBig, kUnknown };

/// conesim's own name of a class: blue, yellow, orange_small, orange_big, unknown.
std::string_view to_string(ConeClass c);

/// Parses conesim's own class name; nullopt when the name is not one of them.
std::optional<ConeClass> cone_class_from_string(std::string_view name);

/// Physical size of a cone class (FSG handbook): base width and height in metres.
struct ConeSize {
  double base_m;
  double height_m;
};

/// Small cones are 228 x 228 x 325 mm, big orange cones 285 x 285 x 505 mm.
ConeSize cone_size(ConeClass c);

}  // namespace conesim::core
