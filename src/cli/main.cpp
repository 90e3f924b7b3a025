// causaldrive: causal imitation learning for urban driving, one binary with subcommands.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "cli/commands.hpp"
#include "core/error.hpp"

namespace {

// CLI11's message for a bad command line, on one line. Its range checks of unbounded numbers
// print the largest double in full; they say what they mean instead.
std::string usage_error(std::string msg) {
  const std::string range = " not in range ", huge = " to 1797693134862315";
  const size_t at = msg.find(range), top = msg.find(huge);
  if (at != std::string::npos && top != std::string::npos && top > at) {
    const std::string low = msg.substr(at + range.size(), top - at - range.size());
    msg = msg.substr(0, at) + (std::strtod(low.c_str(), nullptr) == 0 ? " is not a non-negative number"
                                                   : " is not a positive number");
  }
  for (char& c : msg)
    if (c == '\n') c = ' ';
  return msg;
}

}  // namespace

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
  cd::cli::add_train_expert(app);
  cd::cli::add_eval(app);
  cd::cli::add_suite(app);
  cd::cli::add_probe(app);
  cd::cli::add_diagnose(app);
  cd::cli::add_attention(app);
  cd::cli::add_granger(app);
  cd::cli::add_report(app);
  cd::cli::add_bench(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // A bad command line: one line naming the problem, exit status 2 (usage).
    std::fprintf(stderr, "causaldrive: error: %s (see --help)\n", usage_error(e.what()).c_str());
    return 2;
  } catch (const cd::Error& e) {
    std::fprintf(stderr, "causaldrive: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "causaldrive: internal error: %s\n", e.what());
    return 70;
  }
  return 0;
}
