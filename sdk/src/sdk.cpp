#include <cmath>
#include <numbers>

#include "conesim/sdk/geometry.hpp"
#include "conesim/sdk/version.hpp"

namespace conesim::sdk {

const char* library_version() {
  return kSdkVersion;
}

double normalize_angle(double a) {
  a = std::remainder(a, 2.0 * std::numbers::pi);
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

void transform(const Pose2& pose, double x, double y, double* out_x, double* out_y) {
  const double c = std::cos(pose.yaw_rad), s = std::sin(pose.yaw_rad);
  *out_x = pose.x_m + c * x - s * y;
  *out_y = pose.y_m + s * x + c * y;
}

Pose2 compose(const Pose2& a, const Pose2& b) {
  Pose2 out;
  transform(a, b.x_m, b.y_m, &out.x_m, &out.y_m);
  out.yaw_rad = normalize_angle(a.yaw_rad + b.yaw_rad);
  return out;
}

Pose2 inverse(const Pose2& a) {
  const double c = std::cos(a.yaw_rad), s = std::sin(a.yaw_rad);
  return {-(c * a.x_m + s * a.y_m), s * a.x_m - c * a.y_m, normalize_angle(-a.yaw_rad)};
}

const char* to_string(ConeClass c) {
  switch (c) {
    case ConeClass::kBlue:
      return "blue";
    case ConeClass::kYellow:
      return "yellow";
    case ConeClass::kOrangeSmall:
      return "orange_small";
    case ConeClass::kOrangeBig:
      return "orange_big";
    case ConeClass::kUnknown:
      break;
  }
  return "unknown";
}

}  // namespace conesim::sdk
