#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "cli/commands.hpp"
#include "diagnostics/probe.hpp"

namespace cd::cli {

void add_probe(CLI::App& app) {
  auto opt = std::make_shared<ProbeOptions>();
  auto as_json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand(
      "probe", "copycat probe of a history policy: its output at standstill behind a real, a "
               "moving and a static history");
  sub->add_option("--checkpoint", opt->checkpoint, "checkpoint folder of a history policy (bc-oh, residual, fca, keyframe, hd, dagger)")
      ->required();
  sub->add_option("--data,-d", opt->data,
                 "data folder of `causaldrive collect` (a camera folder is replayed with its "
                 "collect.json)")
      ->required();
  sub->add_option("--max-frames", opt->max_frames,
                  "probe at most this many stopped frames, spread evenly (0 = all)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--moving-speed", opt->moving_speed,
                  "m/s of the synthetic moving history (default 5)")
      ->check(CLI::Range(0.0, 40.0));
  sub->add_flag("--json", *as_json, "print one JSON object instead of the table");
  sub->callback([opt, as_json] {
    ProbeReport r = run_probe(*opt);
    if (*as_json)
      std::printf("%s\n", probe_report_json(r).dump(2).c_str());
    else
      std::printf("%s", probe_report_table(r).c_str());
  });
}

}  // namespace cd::cli
