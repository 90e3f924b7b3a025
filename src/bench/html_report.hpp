#pragma once
// `causaldrive report --html OUT.html RUN...` (SPEC section 13): one self-contained page over
// evaluation runs. It holds the tables `report` prints (the same Markdown, as HTML tables),
// inline SVG charts of success / collision / copycat (and off-road for a free-steering ego)
// per agent and suite with the seeds' spread, and replays of chosen episodes: the frames the
// agent saw (kept by `eval --record`), play / pause / step controls, the trace beside them
// (speed, throttle, brake, steer, causes; MuJoCo-Image: the return so far and the actions) and
// the failure's moment marked. Nothing is fetched
// when it opens: the frames are PNG data URIs, the script and style are inline.
#include <cstdint>
#include <string>
#include <vector>

#include "bench/report.hpp"

namespace cd {

struct HtmlReportOptions {
  std::vector<int> episodes;  // replay these episode indices of every run; empty: the first
                              // failure of each kind (collision, the copycat classes, off-road) per driving
                              // run, the lowest return per MuJoCo-Image run
  int max_frames = 300;       // per replay at most: a longer episode shows every k-th step
  int max_replays = 10;       // on the page at most, in the order of the runs
  uint64_t bootstrap_seed = 0;  // the MuJoCo-Image chart's IQM interval (ReportTable)
  int resamples = 10000;
};

// An episode chosen for a replay.
struct ReplayPick {
  size_t run = 0;       // index into the runs
  int episode = 0;      // the episode's index in its run
  std::string outcome;  // as results.json has it
};

// The episodes the page replays: the asked ones, or per driving run its first failure of each
// kind, per MuJoCo-Image run its episode with the lowest return.
std::vector<ReplayPick> pick_replays(const std::vector<RunResult>& runs,
                                     const HtmlReportOptions& options);

// The step at which a failure shows in a recorded episode: the last step for a collision or an
// off-road end; for stuck (inertia in older records) the first step of the final stretch in
// which the ego stood (speed < kStoppedSpeed) with a free path; for restart_stall, stopped_free
// and blocked the first step of the final standstill; -1 for any other outcome.
long failure_step(const std::string& outcome, const std::vector<float>& speed,
                  const std::vector<float>& path_free);

// The page. `markdown` is what `report` prints for the same runs (its tables are the page's
// tables, row for row).
std::string render_html_report(const std::vector<RunResult>& runs, const std::string& markdown,
                               const HtmlReportOptions& options);

// RFC 4648 base64 of bytes (the page's data URIs).
std::string base64(const std::string& bytes);

}  // namespace cd
