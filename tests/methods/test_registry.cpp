// The method table (methods/registry): the names train accepts and the errors for the others.
#include <gtest/gtest.h>

#include <string>

#include "core/error.hpp"
#include "methods/method.hpp"

namespace cd {
namespace {

TEST(Methods, NamesAndErrors) {
  for (const auto& m : trainable_methods()) EXPECT_NO_THROW(check_train_method(m));
  // Every method of SPEC section 3 but the two agents trains.
  for (const char* m : {"bc-so", "bc-oh", "residual", "fca", "keyframe", "hd", "dagger", "dim",
                        "rip", "cim", "cim-mlp", "cim-entangled"})
    EXPECT_NO_THROW(check_train_method(m)) << m;
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
