// PLACEHOLDER (owner: report) — replaced by the real 'report' subcommand.
#include "cli/commands.hpp"
#include "core/error.hpp"
namespace cd::cli {
void add_report(CLI::App& app) {
  auto* sub = app.add_subcommand("report", "(in progress)");
  sub->allow_extras();
  sub->callback([] { throw Error("'report' is not implemented yet"); });
}
}  // namespace cd::cli
