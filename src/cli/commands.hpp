#pragma once
// Each subcommand registers its options and callback on the root app. Callbacks throw
// cd::Error on bad input; main() turns that into one line and a non-zero exit.
#include <CLI/CLI.hpp>

namespace cd::cli {

void add_town(CLI::App& app);
void add_collect(CLI::App& app);
void add_bench(CLI::App& app);
void add_quickstart(CLI::App& app);
void add_planned(CLI::App& app);  // train, eval, granger, report: not in this version yet

}  // namespace cd::cli
