// The method table (methods/registry): the names train accepts and the errors for the others.
#include <gtest/gtest.h>

#include <string>

#include "core/error.hpp"
#include "methods/method.hpp"

namespace cd {
namespace {

TEST(Methods, NamesAndErrors) {
  for (const auto& m : trainable_methods()) EXPECT_NO_THROW(check_train_method(m));
  try {
    check_train_method("fca");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "method 'fca' is not available in this version (available: bc-so, bc-oh, dim, "
              "rip, cim, cim-mlp, cim-entangled)");
  }
  for (const auto& m : planned_methods()) EXPECT_THROW(check_train_method(m), ConfigError);
  EXPECT_THROW(check_train_method("expert"), ConfigError);
  try {
    check_train_method("bcoh");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown method 'bcoh'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("dagger"), std::string::npos) << "lists the known names";
  }
}

}  // namespace
}  // namespace cd
