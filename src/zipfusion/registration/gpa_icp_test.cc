#include "zipfusion/registration/gpa_icp.h"

#include <gtest/gtest.h>

namespace zipfusion {
namespace {

TEST(RegistrationOptions, ValidateNamesTheField) {
  RegistrationOptions o;
  o.trim_fraction = 1.5;
  EXPECT_THROW(o.validate(), InvalidInput);
}

}  // namespace
}  // namespace zipfusion
