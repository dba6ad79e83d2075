#include "core/cone.hpp"

#include <gtest/gtest.h>

namespace conesim::core {
namespace {

TEST(Cone, NamesRoundTrip) {
  for (ConeClass c : {ConeClass::kBlue, ConeClass::kYellow, ConeClass::kOrangeSmall,
                      ConeClass::kOrangeBig, ConeClass::kUnknown}) {
    EXPECT_EQ(cone_class_from_string(to_string(c)), c);
  }
  EXPECT_FALSE(cone_class_from_string("purple").has_value());
}

TEST(Cone, BigOrangeIsTallerThanSmallCones) {
  EXPECT_DOUBLE_EQ(cone_size(ConeClass::kOrangeBig).height_m, 0.505);
  EXPECT_DOUBLE_EQ(cone_size(ConeClass::kBlue).base_m, 0.228);
}

}  // namespace
}  // namespace conesim::core
