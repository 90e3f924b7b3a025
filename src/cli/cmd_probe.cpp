// PLACEHOLDER (owner: learn) — replaced by the real 'probe' subcommand.
#include "cli/commands.hpp"
#include "core/error.hpp"
namespace cd::cli {
void add_probe(CLI::App& app) {
  auto* sub = app.add_subcommand("probe", "(in progress)");
  sub->allow_extras();
  sub->callback([] { throw Error("'probe' is not implemented yet"); });
}
}  // namespace cd::cli
