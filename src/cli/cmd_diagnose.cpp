#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "diagnostics/diagnose.hpp"

namespace cd::cli {

void add_diagnose(CLI::App& app) {
  auto opt = std::make_shared<DiagnoseOptions>();
  auto as_json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand(
      "diagnose", "what an image policy learned: its action against the expert's label on a data "
                  "folder, situation by situation (standing, starting, cruising, ...)");
  sub->add_option("--checkpoint", opt->checkpoint,
                  "checkpoint folder of a family method (bc-so, bc-oh, residual, fca, keyframe, "
                  "hd, dagger)")
      ->required();
  sub->add_option("--data,-d", opt->data, "data folder of `causaldrive collect`")->required();
  sub->add_option("--split", opt->split,
                  "episodes compared: val (the run's held-out episodes of its own data folder), "
                  "all, or auto (val on the folder it was trained on, else all; the default)")
      ->check(CLI::IsMember({"auto", "val", "all"}));
  sub->add_option("--max-frames", opt->max_frames,
                  "compare at most this many frames, spread evenly (0 = all)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--plots", opt->plots,
                  "write one PNG per chosen episode into this folder: label (black) and "
                  "prediction (red) per component under a strip of situation colours");
  sub->add_option("--plot-episodes", opt->plot_episodes,
                  "episode indices of the data folder to plot (default: the first 3 compared)")
      ->delimiter(',');
  sub->add_flag("--json", *as_json, "print one JSON object (SPEC section 10) instead of the table");
  sub->callback([opt, as_json] {
    DiagnosisReport r = run_diagnosis(*opt);
    if (*as_json)
      std::printf("%s\n", diagnosis_json(r).dump(2).c_str());
    else
      std::printf("%s", diagnosis_table(r).c_str());
  });
}

}  // namespace cd::cli
