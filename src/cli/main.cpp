// causaldrive: causal imitation learning for urban driving, one binary with subcommands.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "cli/commands.hpp"
#include "core/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "causaldrive: collect expert driving in SUMO, train imitation policies, measure inertia "
      "and collisions"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "causaldrive 0.1.0");
  cd::cli::add_quickstart(app);
  cd::cli::add_town(app);
  cd::cli::add_collect(app);
  cd::cli::add_train(app);
  cd::cli::add_eval(app);
  cd::cli::add_suite(app);
  cd::cli::add_probe(app);
  cd::cli::add_attention(app);
  cd::cli::add_granger(app);
  cd::cli::add_report(app);
  cd::cli::add_bench(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const cd::Error& e) {
    std::fprintf(stderr, "causaldrive: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "causaldrive: internal error: %s\n", e.what());
    return 70;
  }
  return 0;
}
