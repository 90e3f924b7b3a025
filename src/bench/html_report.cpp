#include "bench/html_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>

#include "bench/metrics.hpp"
#include "bench/runner.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/png.hpp"
#include "core/text.hpp"
#include "data/h5_episode.hpp"
#include "data/mujoco_episode.hpp"
#include "sense/bev_colour.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::vector<std::string> cells_of(const std::string& row) {
  std::vector<std::string> cells;
  std::string inner(trim(row));
  if (inner.size() >= 2) inner = inner.substr(1, inner.size() - 2);
  std::stringstream in(inner);
  for (std::string c; std::getline(in, c, '|');) cells.push_back(std::string(trim(c)));
  return cells;
}

// `report`'s Markdown as HTML: "## " titles, tables, other lines as paragraphs.
std::string tables_html(const std::string& markdown) {
  std::ostringstream o;
  std::stringstream in(markdown);
  bool in_table = false, header = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("|", 0) == 0) {
      if (line.find("---") != std::string::npos && line.find_first_not_of("|-: ") == std::string::npos)
        continue;  // the separator row
      if (!in_table) {
        o << "<table class=\"metrics\">\n";
        in_table = header = true;
      }
      o << "<tr>";
      for (const std::string& c : cells_of(line))
        o << (header ? "<th>" : "<td>") << escape(c) << (header ? "</th>" : "</td>");
      o << "</tr>\n";
      header = false;
      continue;
    }
    if (in_table) {
      o << "</table>\n";
      in_table = false;
    }
    if (line.rfind("## ", 0) == 0) o << "<h3>" << escape(line.substr(3)) << "</h3>\n";
    else if (!trim(line).empty()) o << "<p>" << escape(line) << "</p>\n";
  }
  if (in_table) o << "</table>\n";
  return o.str();
}

struct Series {
  std::string key, name, colour;
};

// One grouped bar chart per column (suite): a group per label, a bar per series, the mean with
// a whisker of +- one sd over seeds. `scale` turns summary values into the axis' unit.
std::string bar_charts(const ReportTable& table, const std::vector<Series>& series, double scale,
                       const std::string& unit, bool fixed_100) {
  std::ostringstream o;
  for (const std::string& suite : table.suites) {
    std::vector<std::string> labels;
    for (const std::string& l : table.labels)
      if (table.cells.count({l, suite})) labels.push_back(l);
    if (labels.empty()) continue;
    double top = fixed_100 ? 100.0 : 0.0;
    for (const std::string& l : labels)
      for (const Series& s : series)
        if (auto st = table.stats(l, suite, s.key); st && st->n > 0)
          top = std::max({top, std::abs(st->mean * scale) + st->std.value_or(0) * std::abs(scale),
                          st->interval ? st->interval->hi * scale : 0.0});
    if (top <= 0) top = 1;
    const double bar = 16, gap = 28, left = 48, plot_h = 160, top_pad = 14;
    const double group_w = bar * static_cast<double>(series.size()) + gap;
    double legend_w = 0;
    for (const Series& s : series) legend_w += 30 + 8 * static_cast<double>(s.name.size());
    const double width =
        std::max(left + group_w * static_cast<double>(labels.size()) + 10, left + legend_w);
    const double height = top_pad + plot_h + 56;
    o << "<figure class=\"chart\"><figcaption>" << escape(suite) << "</figcaption>\n";
    o << format(
                  "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                  "role=\"img\" aria-label=\"%s\">\n",
                  width, height, escape(suite).c_str());
    for (int tick = 0; tick <= 4; ++tick) {
      const double v = top * tick / 4.0, y = top_pad + plot_h - plot_h * tick / 4.0;
      o << format(
                    "<line x1=\"%.0f\" x2=\"%.0f\" y1=\"%.1f\" y2=\"%.1f\" class=\"grid\"/>"
                    "<text x=\"%.0f\" y=\"%.1f\" class=\"tick\">%.0f%s</text>\n",
                    left, width - 10, y, y, left - 4, y + 4, v, unit.c_str());
    }
    for (size_t g = 0; g < labels.size(); ++g) {
      const double x0 = left + gap / 2 + group_w * static_cast<double>(g);
      for (size_t k = 0; k < series.size(); ++k) {
        auto st = table.stats(labels[g], suite, series[k].key);
        if (!st || st->n == 0) continue;
        const double v = st->mean * scale, sd = st->std.value_or(0) * std::abs(scale);
        const double h = plot_h * std::max(0.0, v) / top, x = x0 + bar * static_cast<double>(k);
        // The whisker: the rate's 95% interval where the runs give one (report's cells), else
        // +- one sd over seeds.
        const bool interval = st->interval.has_value();
        const double lo = interval ? st->interval->lo * scale : v - sd;
        const double hi = interval ? st->interval->hi * scale : v + sd;
        const std::string spread =
            interval ? format("95%% [%.1f, %.1f]", lo, hi) : format("sd %.1f", sd);
        o << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"%.0f\" height=\"%.1f\" fill=\"%s\" "
                    "data-series=\"%s\" data-label=\"%s\" data-value=\"%.4g\"><title>%s, %s: "
                    "%.1f%s (%s, n %d)</title></rect>\n",
                    x, top_pad + plot_h - h, bar - 2, h, series[k].colour.c_str(),
                    series[k].key.c_str(), escape(labels[g]).c_str(), v,
                    escape(labels[g]).c_str(), series[k].name.c_str(), v, unit.c_str(),
                    spread.c_str(), st->n);
        if (interval || st->std) {
          const double y1 = top_pad + plot_h - plot_h * std::max(0.0, lo) / top;
          const double y2 = top_pad + plot_h - plot_h * std::min(top, hi) / top;
          const double cx = x + (bar - 2) / 2;
          o << format("<line x1=\"%.1f\" x2=\"%.1f\" y1=\"%.1f\" y2=\"%.1f\" class=\"%s\"/>\n", cx,
                      cx, y1, y2, interval ? "ci" : "sd");
        }
      }
      o << format(
                    "<text x=\"%.1f\" y=\"%.0f\" class=\"group\">%s</text>\n",
                    x0 + bar * static_cast<double>(series.size()) / 2, top_pad + plot_h + 16,
                    escape(labels[g]).c_str());
    }
    double lx = left;
    for (const Series& s : series) {
      o << format(
                    "<rect x=\"%.0f\" y=\"%.0f\" width=\"10\" height=\"10\" fill=\"%s\"/>"
                    "<text x=\"%.0f\" y=\"%.0f\" class=\"legend\">%s</text>\n",
                    lx, height - 18, s.colour.c_str(), lx + 14, height - 9, s.name.c_str());
      lx += 14 + 8 * static_cast<double>(s.name.size()) + 16;
    }
    o << "</svg></figure>\n";
  }
  return o.str();
}

std::string charts_html(const std::vector<RunResult>& runs, const HtmlReportOptions& options) {
  ReportTable table = build_report(runs);
  table.bootstrap_seed = options.bootstrap_seed;
  table.resamples = options.resamples;
  const bool all_mujoco = std::all_of(runs.begin(), runs.end(), [](const RunResult& r) { return r.mujoco; });
  if (all_mujoco)
    return bar_charts(table, {{kIqmReturn, "IQM return", "#4e79a7"}}, 1.0, "", false);
  std::vector<Series> series = {{"success_rate", "success", "#59a14f"},
                                {"collision_rate", "collision", "#e15759"},
                                {"copycat_rate", "copycat", "#f28e2b"}};
  if (std::any_of(runs.begin(), runs.end(), [](const RunResult& r) { return steers_freely(r); }))
    series.push_back({"offroad_rate", "off-road", "#9c755f"});
  return bar_charts(table, series, 100.0, "%", true);
}

json results_of(const RunResult& run) {
  try {
    return json::parse(read_file_bytes(run.path));
  } catch (const json::exception& e) {
    throw DataError(run.path + ": " + e.what());
  }
}

json series(const std::string& name, const std::string& label, const std::string& colour,
            const json& values, double range) {
  return {{"name", name}, {"label", label}, {"colour", colour}, {"values", values},
          {"lo", -range}, {"hi", range}};
}

double round3(double v) { return std::round(v * 1000.0) / 1000.0; }

double largest(const json& values) {
  double m = 1e-6;
  for (const json& v : values) m = std::max(m, std::abs(v.get<double>()));
  return m;
}

// The replay of one recorded episode, as the JSON the page's script reads (frames as PNG data
// URIs, the steps shown, their series and causes, the failure's mark); null with *missing set
// when the episode has no recording.
json replay_json(const RunResult& run, const ReplayPick& pick, const HtmlReportOptions& o,
                 std::string* missing) {
  const std::string file = (fs::path(run.path).parent_path() / "episodes" /
                            episode_recording_name(pick.episode)).string();
  if (!fs::exists(file)) {
    *missing = "not recorded (run eval with --record to keep its frames): " + file;
    return nullptr;
  }
  const std::string title = run.label + " on " + run.column() + ", episode " +
                            std::to_string(pick.episode) + ": " + pick.outcome;
  json r = {{"title", title}, {"outcome", pick.outcome}, {"file", file}, {"mark", nullptr},
            {"mark_label", ""}};
  json frames = json::array(), time = json::array(), shown = json::array();
  auto keep = [&](long steps, int max_frames) {
    return std::max<long>(1, (steps + max_frames - 1) / std::max(1, max_frames));
  };
  if (run.mujoco) {
    const MujocoEpisode e = read_mujoco_episode(file);
    const long steps = static_cast<long>(e.frames()), stride = keep(steps, o.max_frames);
    const size_t A = static_cast<size_t>(e.action_dim);
    std::vector<uint8_t> rgb(static_cast<size_t>(e.height) * e.width * 3);
    const size_t plane = static_cast<size_t>(e.height) * e.width;
    json ret = json::array();
    std::vector<json> actions(A, json::array());
    double sum = 0;
    for (long t = 0; t < steps; ++t) {
      sum += e.reward[static_cast<size_t>(t)];
      if (t % stride) continue;
      const uint8_t* f = e.obs.data() + static_cast<size_t>(t) * e.frame_bytes();
      for (size_t p = 0; p < plane; ++p)  // C x H x W planes -> interleaved RGB
        for (size_t c = 0; c < 3; ++c) rgb[p * 3 + c] = f[c * plane + p];
      frames.push_back("data:image/png;base64," + base64(encode_png(rgb, e.width, e.height, 3)));
      shown.push_back(t);
      time.push_back(round3(static_cast<double>(t) * e.dt));
      ret.push_back(round3(sum));
      for (size_t j = 0; j < A; ++j) actions[j].push_back(round3(e.action[static_cast<size_t>(t) * A + j]));
    }
    json list = {series("return", "return", "#4e79a7", ret, largest(ret))};
    double arange = 1e-6;
    for (const json& a : actions) arange = std::max(arange, largest(a));
    static const char* colours[] = {"#59a14f", "#e15759", "#f28e2b", "#b07aa1", "#76b7b2",
                                    "#edc948", "#ff9da7", "#9c755f"};
    for (size_t j = 0; j < A; ++j)
      list.push_back(series("a" + std::to_string(j), "a" + std::to_string(j), colours[j % 8],
                            actions[j], arange));
    r.update({{"dt", e.dt}, {"steps", steps}, {"stride", stride}, {"series", list},
              {"causes", json::object()}});
  } else {
    EpisodeMeta meta;
    const EpisodeData d = read_episode(file, &meta);
    const long steps = static_cast<long>(d.frames()), stride = keep(steps, o.max_frames);
    const size_t a = static_cast<size_t>(std::max(1, d.action_dim));
    std::vector<uint8_t> planes(d.frame_bytes());
    json speed = json::array(), throttle = json::array(), brake = json::array(),
         steer = json::array(), causes = json::object();
    for (long t = 0; t < steps; t += stride) {
      const size_t u = static_cast<size_t>(t);
      d.frame_planes(u, planes.data());
      const std::vector<uint8_t> rgb =
          frame_picture(planes.data(), d.channels, d.height, d.width, d.camera());
      frames.push_back("data:image/png;base64," + base64(encode_png(rgb, d.width, d.height, 3)));
      shown.push_back(t);
      time.push_back(round3(static_cast<double>(t) * meta.dt));
      speed.push_back(round3(d.speed[u]));
      throttle.push_back(round3(d.action[u * a]));
      brake.push_back(round3(a > 1 ? d.action[u * a + 1] : 0.0));
      if (a > 2) steer.push_back(round3(d.action[u * a + 2]));
      for (const char* c : {"path_free", "tl_state", "lead_distance", "ped_on_path",
                            "junction_distance"}) {
        auto it = d.causes.find(c);
        if (it != d.causes.end()) causes[c].push_back(round3(it->second[u]));
      }
    }
    json list = {series("speed", "speed m/s", "#4e79a7", speed, largest(speed)),
                 series("throttle", "throttle", "#59a14f", throttle, 1.0),
                 series("brake", "brake", "#e15759", brake, 1.0)};
    if (a > 2) list.push_back(series("steer", "steer", "#b07aa1", steer, 1.0));
    static const std::vector<float> none;
    auto pf = d.causes.find("path_free");
    const long mark = failure_step(pick.outcome, d.speed, pf == d.causes.end() ? none : pf->second);
    // What held the path when the final standstill began (the episode's taxonomy record).
    std::string cause;
    for (const RunEpisode& e : run.episodes)
      if (e.index == pick.episode && !e.stop_cause.empty()) cause = e.stop_cause;
    std::replace(cause.begin(), cause.end(), '_', ' ');
    const std::string standstill =
        pick.outcome + ": the standstill starts" + (cause.empty() ? "" : " (path: " + cause + ")");
    r.update({{"dt", meta.dt}, {"steps", steps}, {"stride", stride}, {"series", list},
              {"causes", causes},
              {"mark", mark < 0 ? json(nullptr) : json(mark / stride)},
              {"mark_label", pick.outcome == "collision" || pick.outcome == "offroad"
                                 ? pick.outcome
                                 : standstill}});
  }
  r.update({{"frames", frames}, {"time", time}, {"step", shown}});
  return r;
}

const char* kStyle = R"css(
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1200px; }
h1 { font-size: 1.5em; } h2 { margin-top: 1.6em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1em; margin-top: 1.2em; }
table.metrics { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.85em; }
table.metrics th, table.metrics td { border: 1px solid #ccc; padding: 3px 7px; text-align: right; }
table.metrics th:first-child, table.metrics td:first-child { text-align: left; }
table.metrics th { background: #f3f3f3; }
figure.chart { display: inline-block; margin: 0 1.5em 1em 0; }
figcaption { font-weight: 600; font-size: 0.9em; }
svg .grid { stroke: #e5e5e5; } svg .sd, svg .ci { stroke: #222; stroke-width: 1.5; }
svg .tick { font-size: 10px; text-anchor: end; fill: #666; }
svg .group { font-size: 11px; text-anchor: middle; } svg .legend { font-size: 11px; }
section.replay { border: 1px solid #ccc; padding: 0.8em; margin: 1em 0; }
section.replay .body { display: flex; gap: 1.2em; align-items: flex-start; flex-wrap: wrap; }
section.replay img.frame { width: 320px; height: 320px; image-rendering: pixelated; background: #111; }
section.replay .controls button { margin-right: 0.3em; }
section.replay .controls input[type=range] { width: 320px; }
section.replay .values { font: 12px monospace; white-space: pre; }
section.replay svg .cursor { stroke: #000; stroke-width: 1.5; }
section.replay svg .mark { stroke: #d00; stroke-width: 2; stroke-dasharray: 4 2; }
section.replay svg .marktext { fill: #d00; font-size: 11px; }
p.missing { color: #a00; }
)css";

// The replays' player: every section.replay reads its JSON and drives its picture, its trace
// chart (one polyline per series, a cursor, the failure mark) and its values panel.
const char* kScript = R"js(
(function () {
  const W = 640, H = 220, PAD = 24;
  const NS = "http://www.w3.org/2000/svg";
  function el(name, attrs) {
    const e = document.createElementNS(NS, name);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    return e;
  }
  document.querySelectorAll("section.replay").forEach(function (sec) {
    const data = JSON.parse(sec.querySelector("script.replay-data").textContent);
    const n = data.frames.length;
    const img = sec.querySelector("img.frame");
    const slider = sec.querySelector("input.seek");
    const values = sec.querySelector(".values");
    const svg = sec.querySelector("svg.trace");
    slider.max = String(n - 1);
    const x = function (i) { return PAD + (W - 2 * PAD) * (n > 1 ? i / (n - 1) : 0); };
    // Each series on its own range [lo, hi] (symmetric about zero: zero is the middle line).
    const y = function (v, s) {  // the curves above the two strips
      const u = Math.max(0, Math.min(1, (v - s.lo) / (s.hi - s.lo)));
      return PAD + (H - 2 * PAD - 18) * (1 - u);
    };
    const MID = PAD + (H - 2 * PAD - 18) / 2;  // zero of the symmetric series
    svg.appendChild(el("line", {x1: PAD, x2: W - PAD, y1: MID, y2: MID, stroke: "#ccc"}));
    let lx = PAD;
    for (const s of data.series) {
      let pts = "";
      for (let i = 0; i < s.values.length; i++) pts += x(i).toFixed(1) + "," + y(s.values[i], s).toFixed(1) + " ";
      svg.appendChild(el("polyline", {points: pts, fill: "none", stroke: s.colour, "stroke-width": 1.3, "data-series": s.name}));
      const t = el("text", {x: lx, y: 12, fill: s.colour, "font-size": 11});
      t.textContent = s.label;
      svg.appendChild(t);
      lx += 12 + 7 * s.label.length;
    }
    if (data.mark !== null) {
      svg.appendChild(el("line", {x1: x(data.mark), x2: x(data.mark), y1: PAD / 2, y2: H - PAD / 2, class: "mark"}));
      const right = x(data.mark) > W / 2;  // the label on the side with room
      const t = el("text", {x: x(data.mark) + (right ? -3 : 3), y: H - 6, class: "marktext",
                            "text-anchor": right ? "end" : "start"});
      t.textContent = data.mark_label + " (" + data.time[data.mark].toFixed(1) + " s)";
      svg.appendChild(t);
    }
    // Two strips under the curves: the light ahead and whether the path is free, step by step.
    const LIGHT = {0: "none", 1: "red", 2: "yellow", 3: "green", 4: "green (yield)"};
    const LIGHT_COLOUR = {1: "#e15759", 2: "#edc948", 3: "#59a14f", 4: "#8cd17d"};
    function strip(values, top, colour_of, name) {
      if (!values) return;
      const w = (W - 2 * PAD) / Math.max(1, n - 1);
      for (let k = 0; k < n; k++) {
        const c = colour_of(values[k]);
        if (c) svg.appendChild(el("rect", {x: (x(k) - w / 2).toFixed(1), y: top, width: (w + 0.3).toFixed(2),
                                           height: 6, fill: c, class: "strip", "data-strip": name}));
      }
      const t = el("text", {x: W - PAD + 3, y: top + 6, "font-size": 9, fill: "#555"});
      t.textContent = name;
      svg.appendChild(t);
    }
    strip(data.causes.tl_state, H - PAD - 14, function (v) { return LIGHT_COLOUR[v]; }, "light");
    strip(data.causes.path_free, H - PAD - 6, function (v) { return v > 0.5 ? "#59a14f" : "#bbb"; }, "free");
    const cursor = el("line", {x1: x(0), x2: x(0), y1: PAD / 2, y2: H - PAD / 2, class: "cursor"});
    svg.appendChild(cursor);
    let i = 0, timer = null;
    function show(k) {
      i = Math.max(0, Math.min(n - 1, k));
      img.src = data.frames[i];
      slider.value = String(i);
      cursor.setAttribute("x1", x(i).toFixed(1));
      cursor.setAttribute("x2", x(i).toFixed(1));
      sec.setAttribute("data-frame", String(i));
      let text = "t " + data.time[i].toFixed(2) + " s (step " + data.step[i] + " of " + data.steps + ")";
      for (const s of data.series) text += "\n" + s.label.padEnd(18) + s.values[i].toFixed(3);
      for (const c in data.causes) {
        const v = data.causes[c][i];
        const word = c === "tl_state" ? LIGHT[v] : c === "path_free" ? (v > 0.5 ? "free" : "blocked")
                   : c === "ped_on_path" ? (v > 0.5 ? "yes" : "no") : v;
        text += "\n" + (c === "tl_state" ? "light" : c).padEnd(18) + (word === undefined ? v : word);
      }
      if (data.mark !== null && i >= data.mark) text += "\n>> " + data.mark_label;
      values.textContent = text;
    }
    function pause() { if (timer) { clearInterval(timer); timer = null; } }
    function play() {
      if (timer) return;
      if (i >= n - 1) show(0);
      timer = setInterval(function () { if (i >= n - 1) pause(); else show(i + 1); },
                          1000 * data.dt * data.stride);
    }
    sec.querySelector("button.play").addEventListener("click", play);
    sec.querySelector("button.pause").addEventListener("click", pause);
    sec.querySelector("button.step-back").addEventListener("click", function () { pause(); show(i - 1); });
    sec.querySelector("button.step").addEventListener("click", function () { pause(); show(i + 1); });
    sec.querySelector("button.to-mark").addEventListener("click", function () {
      pause(); show(data.mark === null ? n - 1 : data.mark);
    });
    slider.addEventListener("input", function () { pause(); show(parseInt(slider.value, 10)); });
    show(0);
  });
})();
)js";

}  // namespace

std::string base64(const std::string& bytes) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                       (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += abc[(v >> 6) & 63];
    out += abc[v & 63];
  }
  if (i < bytes.size()) {
    unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? abc[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

long failure_step(const std::string& outcome, const std::vector<float>& speed,
                  const std::vector<float>& path_free) {
  const long n = static_cast<long>(speed.size());
  if (n == 0) return -1;
  if (outcome == "collision" || outcome == "offroad") return n - 1;
  // stuck (inertia in older records): the final stretch stood with the path free; the other
  // classes of a standing end: the start of the final standstill.
  const bool stuck = outcome == "stuck" || outcome == "inertia";
  if (!stuck && outcome != "restart_stall" && outcome != "stopped_free" && outcome != "blocked")
    return -1;
  long t = n;
  while (t > 0 && speed[static_cast<size_t>(t - 1)] < kStoppedSpeed &&
         (!stuck || path_free.empty() || path_free[static_cast<size_t>(t - 1)] > 0.5))
    --t;
  return t < n ? t : n - 1;
}

std::vector<ReplayPick> pick_replays(const std::vector<RunResult>& runs,
                                     const HtmlReportOptions& o) {
  std::vector<ReplayPick> picks;
  for (size_t r = 0; r < runs.size(); ++r) {
    const json res = results_of(runs[r]);
    const json& eps = res.at("episodes");
    auto add = [&](int i) {
      if (static_cast<int>(picks.size()) < o.max_replays)
        picks.push_back({r, i, eps.at(static_cast<size_t>(i)).value("outcome", "")});
    };
    if (!o.episodes.empty()) {
      for (int i : o.episodes)
        if (i >= 0 && static_cast<size_t>(i) < eps.size()) add(i);
      continue;
    }
    if (runs[r].mujoco) {  // MuJoCo-Image: the episode with the lowest return
      size_t worst = 0;
      for (size_t i = 1; i < eps.size(); ++i)
        if (eps[i].value("return", 0.0) < eps[worst].value("return", 0.0)) worst = i;
      if (!eps.empty() && static_cast<int>(picks.size()) < o.max_replays) {
        char what[64];
        std::snprintf(what, sizeof what, "lowest return, %.1f", eps[worst].value("return", 0.0));
        picks.push_back({r, static_cast<int>(worst), what});
      }
      continue;
    }
    for (const char* kind :
         {"collision", "stuck", "inertia", "restart_stall", "stopped_free", "offroad"})
      for (size_t i = 0; i < eps.size(); ++i)
        if (eps[i].value("outcome", "") == kind) {
          add(static_cast<int>(i));
          break;
        }
  }
  return picks;
}

std::string render_html_report(const std::vector<RunResult>& runs, const std::string& markdown,
                               const HtmlReportOptions& o) {
  std::ostringstream page;
  page << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
       << "<title>causaldrive report</title>\n<style>" << kStyle << "</style></head><body>\n"
       << "<h1>causaldrive report</h1>\n<p>" << runs.size()
       << " evaluation run(s). Whiskers and brackets: 95% intervals over training seeds and their "
          "episodes where the runs list their episodes; else &plusmn; sd over seeds.</p>\n";
  page << "<h2 id=\"charts\">Charts</h2>\n" << charts_html(runs, o);
  page << "<h2 id=\"tables\">Tables</h2>\n" << tables_html(markdown);
  page << "<h2 id=\"replays\">Replays</h2>\n";
  const std::vector<ReplayPick> picks = pick_replays(runs, o);
  if (picks.empty())
    page << "<p>No episode to replay: no failure in these runs (choose episodes with "
            "--episodes).</p>\n";
  int id = 0;
  for (const ReplayPick& pick : picks) {
    std::string missing;
    const json r = replay_json(runs[pick.run], pick, o, &missing);
    const std::string title = runs[pick.run].label + " on " + runs[pick.run].column() +
                              ", episode " + std::to_string(pick.episode) + ": " + pick.outcome;
    if (r.is_null()) {
      page << "<h3>" << escape(title) << "</h3>\n<p class=\"missing\">" << escape(missing)
           << "</p>\n";
      continue;
    }
    std::string data = r.dump();
    // Inside <script>: "</" would end the element early.
    for (size_t at = 0; (at = data.find("</", at)) != std::string::npos; at += 3)
      data.replace(at, 2, "<\\/");
    page << "<section class=\"replay\" id=\"replay-" << id++ << "\" data-frame=\"0\">\n<h3>"
         << escape(title) << "</h3>\n<div class=\"body\"><div><img class=\"frame\" alt=\"BEV frame\">"
         << "<div class=\"controls\"><button class=\"play\">play</button><button "
            "class=\"pause\">pause</button><button class=\"step-back\">&#9664; step</button>"
            "<button class=\"step\">step &#9654;</button><button class=\"to-mark\">"
         << (r["mark"].is_null() ? "end" : "failure") << "</button><br>"
         << "<input class=\"seek\" type=\"range\" min=\"0\" value=\"0\"></div></div>\n"
         << "<svg class=\"trace\" xmlns=\"http://www.w3.org/2000/svg\" width=\"640\" "
            "height=\"220\"></svg>\n<div class=\"values\"></div></div>\n"
         << "<script type=\"application/json\" class=\"replay-data\">" << data
         << "</script>\n</section>\n";
  }
  page << "<script>" << kScript << "</script>\n</body></html>\n";
  return page.str();
}

}  // namespace cd
