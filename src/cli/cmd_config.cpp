// `causaldrive config [--config C] [--reference]`: the effective settings of a config (the
// built-in defaults overridden by the file) as JSON, or the Markdown reference of every key
// (docs/configuration.md is its output).
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "app/settings_reference.hpp"
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"

namespace cd::cli {

void add_config(CLI::App& app) {
  struct Args {
    std::string config;
    bool reference = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand(
      "config", "print the effective settings of a config as JSON, or the reference of every key");
  sub->add_option("--config,-c", a->config, "TOML config (default: the built-in quickstart)");
  sub->add_flag("--reference", a->reference,
                "print the Markdown reference of every table and key (docs/configuration.md)");
  sub->callback([a] {
    if (a->reference) {
      if (!a->config.empty()) throw ConfigError("--reference describes every key; it takes no --config");
      std::fputs(settings_reference_markdown().c_str(), stdout);
      return;
    }
    std::printf("%s\n", settings_to_json(settings_from(a->config)).dump(2).c_str());
  });
}

}  // namespace cd::cli
