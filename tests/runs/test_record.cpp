// refuse_other_run (runs/record): the check every trainer makes before resuming a folder. A key
// the stored record lacks (a record written before the key existed) counts as its default;
// a key whose value differs refuses the folder in one line naming it.
#include "runs/record.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "app/settings.hpp"
#include "core/error.hpp"

namespace cd {
namespace {

TEST(RefuseOtherRun, MissingKeysTakeTheirDefaultsAndChangedKeysRefuse) {
  const nlohmann::json now = settings_to_json(Settings{});
  nlohmann::json old_record = now;
  old_record["model"].erase("head");        // keys added after the run was trained
  old_record["train"].erase("weight_decay");
  old_record.erase("mujoco");
  const std::vector<std::string> tables = {"model", "train"};
  auto never = [](const std::string&, const std::string&) { return false; };
  EXPECT_NO_THROW(refuse_other_run({"bc-oh", old_record, "data"}, {"bc-oh", now, "data"}, "dir",
                                   tables, never));

  nlohmann::json changed = old_record;
  changed["train"]["lr"] = 0.5;
  try {
    refuse_other_run({"bc-oh", changed, "data"}, {"bc-oh", now, "data"}, "dir", tables, never);
    FAIL() << "a run of another learning rate was resumed";
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("train.lr"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("model.head"), std::string::npos) << "a missing key is not a difference: " << msg;
  }
  // A stored value other than the default of a key the run now sets is still a difference.
  nlohmann::json linear = now;
  linear["model"]["head"] = "linear";
  EXPECT_THROW(refuse_other_run({"bc-oh", linear, "data"}, {"bc-oh", now, "data"}, "dir", tables,
                                never),
               ConfigError);
}

}  // namespace
}  // namespace cd
