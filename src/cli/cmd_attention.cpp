#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "diagnostics/attention.hpp"

namespace cd::cli {

void add_attention(CLI::App& app) {
  auto opt = std::make_shared<AttentionOptions>();
  auto as_json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand(
      "attention", "Grad-CAM attention maps of an image policy over recorded frames (BEV or camera): one PNG "
                   "per frame (frame | map | overlay) and attention.json");
  sub->add_option("--checkpoint", opt->checkpoint,
                  "checkpoint folder of an image policy (bc-so, bc-oh, residual, fca, keyframe, "
                  "hd, dagger)")
      ->required();
  sub->add_option("--data,-d", opt->data, "data folder of `causaldrive collect`")->required();
  sub->add_option("--out,-o", opt->out, "output folder for the PNGs and attention.json")
      ->required();
  sub->add_option("--frames", opt->frames,
                  "number of frames, spread evenly over the selected ones (default 16)");
  sub->add_option("--select", opt->select,
                  "which frames: stopped (speed < 0.5 m/s, default), all, or light (a traffic "
                  "light nearer than 30 m)");
  sub->add_option("--scale", opt->scale, "pixels per BEV pixel in the PNGs (default 4)");
  sub->add_flag("--json", *as_json, "print attention.json instead of the table");
  sub->callback([opt, as_json] {
    AttentionReport r = run_attention(*opt);
    if (*as_json)
      std::printf("%s\n", attention_report_json(r).dump(2).c_str());
    else
      std::printf("%s", attention_report_table(r).c_str());
  });
}

}  // namespace cd::cli
