// The World's names that need no simulator (a build without SUMO has them too).
#include "world/world.hpp"

namespace cd {

const char* outcome_name(Outcome o) {
  switch (o) {
    case Outcome::Running: return "running";
    case Outcome::Success: return "success";
    case Outcome::Collision: return "collision";
    case Outcome::Timeout: return "timeout";
    case Outcome::Offroad: return "offroad";
  }
  return "?";
}

const std::vector<std::string>& scenario_names() {
  static const std::vector<std::string> names = {"route", "red_light", "leader"};
  return names;
}

}  // namespace cd
