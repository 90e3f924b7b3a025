// PLACEHOLDER (owner: learn) — replaced by the real 'train' subcommand.
#include "cli/commands.hpp"
#include "core/error.hpp"
namespace cd::cli {
void add_train(CLI::App& app) {
  auto* sub = app.add_subcommand("train", "(in progress)");
  sub->allow_extras();
  sub->callback([] { throw Error("'train' is not implemented yet"); });
}
}  // namespace cd::cli
