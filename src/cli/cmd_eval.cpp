// PLACEHOLDER (owner: me) — replaced by the real 'eval' subcommand.
#include "cli/commands.hpp"
#include "core/error.hpp"
namespace cd::cli {
void add_eval(CLI::App& app) {
  auto* sub = app.add_subcommand("eval", "(in progress)");
  sub->allow_extras();
  sub->callback([] { throw Error("'eval' is not implemented yet"); });
}
}  // namespace cd::cli
