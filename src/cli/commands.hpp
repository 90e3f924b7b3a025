#pragma once
// Each subcommand registers its options and callback on the root app. Callbacks throw
// cd::Error on bad input; main() turns that into one line and a non-zero exit.
#include <CLI/CLI.hpp>

namespace cd::cli {

void add_town(CLI::App& app);
void add_collect(CLI::App& app);
void add_train(CLI::App& app);
void add_eval(CLI::App& app);
void add_suite(CLI::App& app);
void add_probe(CLI::App& app);
void add_diagnose(CLI::App& app);
void add_attention(CLI::App& app);
void add_report(CLI::App& app);
void add_bench(CLI::App& app);
void add_quickstart(CLI::App& app);
void add_granger(CLI::App& app);
void add_train_expert(CLI::App& app);
void add_config(CLI::App& app);

}  // namespace cd::cli
