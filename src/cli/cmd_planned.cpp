#include "cli/commands.hpp"
#include "core/error.hpp"

namespace cd::cli {

void add_planned(CLI::App& app) {
  struct Planned {
    const char* name;
    const char* what;
  };
  static const Planned planned[] = {
      {"granger", "Granger-causality tests of candidate variables against a target"},
  };
  for (const Planned& p : planned) {
    CLI::App* sub = app.add_subcommand(p.name, std::string(p.what) + " (not in this version)");
    sub->allow_extras();
    std::string name = p.name;
    sub->callback([name] {
      throw Error("'" + name + "' is not implemented in this version of causaldrive yet; "
                  "see README.md for what is available");
    });
  }
}

}  // namespace cd::cli
