#include "diagnostics/diagnose.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/png.hpp"
#include "datasets/split.hpp"
#include "inference/policy_runner.hpp"
#include "runs/record.hpp"

namespace cd {

using nlohmann::json;

namespace {

// Sums of one (situation, component) cell.
struct Cell {
  long n = 0;
  double sy = 0, syy = 0, sp = 0, spp = 0, sabs = 0, ssq = 0;
  void add(double y, double p) {
    ++n;
    sy += y;
    syy += y * y;
    sp += p;
    spp += p * p;
    sabs += std::abs(p - y);
    ssq += (p - y) * (p - y);
  }
  ComponentStats stats() const {
    ComponentStats c;
    c.count = n;
    if (n == 0) return c;
    const double N = static_cast<double>(n);
    c.label_mean = sy / N;
    c.pred_mean = sp / N;
    c.label_sd = std::sqrt(std::max(0.0, syy / N - c.label_mean * c.label_mean));
    c.pred_sd = std::sqrt(std::max(0.0, spp / N - c.pred_mean * c.pred_mean));
    c.mae = sabs / N;
    const double sst = std::max(0.0, syy - sy * sy / N);
    // Constant labels: R^2 is 1 for a perfect prediction and undefined otherwise.
    if (sst > 1e-12 * std::max(1.0, syy)) {
      c.r2 = 1.0 - ssq / sst;
      c.r2_defined = true;
    } else if (ssq <= 1e-12 * std::max(1.0, syy)) {
      c.r2 = 1.0;
      c.r2_defined = true;
    }
    return c;
  }
};

std::vector<std::string> components_of(const Checkpoint& ck) {
  if (ck.model.action_head == "target_speed") return {"target_speed"};
  std::vector<std::string> c;
  if (ck.input.domain == kDrivingDomain) {
    c = {"throttle", "brake", "steer"};
    c.resize(static_cast<size_t>(std::min(ck.input.action_dim, 3)));
    for (int i = 3; i < ck.input.action_dim; ++i) c.push_back("a" + std::to_string(i));
  } else {
    for (int i = 0; i < ck.input.action_dim; ++i) c.push_back("a" + std::to_string(i));
  }
  return c;
}

// Which episodes are compared: the run's validation episodes (its own data folder), or all.
// The run's record names its validation files; a record made before it did gives only their
// count, and the episodes are drawn again as training drew them (right while the folder is
// unchanged).
std::vector<int> chosen_episodes(const DiagnoseOptions& o, const Checkpoint& ck,
                                 const EpisodeSet& set, std::string& split) {
  const int n = static_cast<int>(set.episodes.size());
  const bool own = canonical_dir(o.data) == ck.data_dir;
  split = o.split == "auto" ? (own ? "val" : "all") : o.split;
  std::vector<int> all(n);
  for (int e = 0; e < n; ++e) all[e] = e;
  if (split == "all") return all;
  if (!own)
    throw ConfigError("--split val: " + o.data + " is not the data folder " + o.checkpoint +
                      " was trained on (" + ck.data_dir + "); use --split all");
  if (!ck.val_files.empty()) {
    std::vector<int> val;
    for (const std::string& file : ck.val_files) {
      auto it = std::find_if(set.episodes.begin(), set.episodes.end(),
                             [&](const PackedEpisode& e) { return e.file == file; });
      if (it == set.episodes.end())
        throw DataError(o.data + " no longer holds " + file + ", a validation episode of " +
                        o.checkpoint + "; use --split all");
      val.push_back(static_cast<int>(it - set.episodes.begin()));
    }
    return val;
  }
  const json& train = ck.settings.at("train");
  std::vector<int> val = choose_val_episodes(n, train.at("val_fraction").get<double>(),
                                             train.at("seed").get<uint64_t>());
  if (static_cast<int>(val.size()) != ck.val_episodes)
    throw DataError(o.data + " now gives " + std::to_string(val.size()) +
                    " validation episodes, the run held out " + std::to_string(ck.val_episodes) +
                    ": the data changed; use --split all");
  return val;
}

void set_pixel(std::vector<uint8_t>& img, int W, int H, int x, int y, const uint8_t rgb[3]) {
  if (x < 0 || y < 0 || x >= W || y >= H) return;
  uint8_t* p = img.data() + 3 * (static_cast<size_t>(y) * W + x);
  p[0] = rgb[0];
  p[1] = rgb[1];
  p[2] = rgb[2];
}

void draw_line(std::vector<uint8_t>& img, int W, int H, int x0, int y0, int x1, int y1,
               const uint8_t rgb[3]) {
  const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  while (true) {
    set_pixel(img, W, H, x0, y0, rgb);
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * err;
    if (e2 >= dy) err += dy, x0 += sx;
    if (e2 <= dx) err += dx, y0 += sy;
  }
}

}  // namespace

DiagnosisReport summarize_diagnosis(const std::vector<std::string>& components,
                                    const std::vector<DiagnosedFrame>& frames,
                                    const std::vector<uint32_t>& situations,
                                    const std::string& domain) {
  if (frames.size() != situations.size())
    throw Error("summarize_diagnosis: " + std::to_string(frames.size()) + " frames, " +
                std::to_string(situations.size()) + " situation masks");
  const size_t A = components.size();
  const int S = domain == kDrivingDomain ? kSituationCount : 1;
  std::vector<std::vector<Cell>> cells(S, std::vector<Cell>(A));
  std::vector<long> counts(S, 0);
  for (size_t i = 0; i < frames.size(); ++i) {
    const DiagnosedFrame& f = frames[i];
    if (f.label.size() != A || f.prediction.size() != A)
      throw Error("summarize_diagnosis: a frame has " + std::to_string(f.label.size()) +
                  " labels and " + std::to_string(f.prediction.size()) + " predictions for " +
                  std::to_string(A) + " components");
    for (int s = 0; s < S; ++s) {
      if (!((situations[i] >> s) & 1u)) continue;
      ++counts[s];
      for (size_t a = 0; a < A; ++a) cells[s][a].add(f.label[a], f.prediction[a]);
    }
  }
  DiagnosisReport r;
  r.domain = domain;
  r.components = components;
  r.frames = static_cast<long>(frames.size());
  for (int s = 0; s < S; ++s) {
    SituationStats st;
    st.name = situation_names()[s];
    st.count = counts[s];
    for (size_t a = 0; a < A; ++a) st.components.push_back(cells[s][a].stats());
    r.situations.push_back(std::move(st));
  }
  return r;
}

DiagnosisReport run_diagnosis(const DiagnoseOptions& o) {
  if (o.split != "auto" && o.split != "val" && o.split != "all")
    throw ConfigError("--split must be auto, val or all, not '" + o.split + "'");
  set_torch_threads(1);
  PolicyRunner policy(o.checkpoint);
  const Checkpoint& ck = policy.checkpoint();
  EpisodeSet set = load_episode_set(o.data);
  require_same_frames(set, ck.input, o.data);
  if (set.domain != ck.input.domain)
    throw DataError("data in " + o.data + " is " + set.domain + " data, the checkpoint " +
                    o.checkpoint + " was trained on " + ck.input.domain + " data");
  if (ck.model.action_head != "target_speed" && set.action_dim != ck.input.action_dim)
    throw DataError("data in " + o.data + " records " + std::to_string(set.action_dim) +
                    " action components, the checkpoint " + o.checkpoint + " predicts " +
                    std::to_string(ck.input.action_dim));
  std::string split;
  const std::vector<int> episodes = chosen_episodes(o, ck, set, split);
  const std::vector<std::string> components = components_of(ck);
  const bool speed_head = ck.model.action_head == "target_speed";
  const bool driving = set.domain == kDrivingDomain;
  const int K = policy.history(), stride = policy.stride();
  const int A = set.action_dim;

  struct Ref {
    int e, t;
  };
  std::vector<Ref> refs;
  for (int e : episodes) {
    const PackedEpisode& ep = set.episodes[e];
    for (int t = (K - 1) * stride; t < ep.frames; ++t) {
      // The target-speed label is the next speed the expert reached (datasets/dataset.hpp).
      if (speed_head && (t + 1 >= ep.frames || !expert_motion(ep, t, t + 1))) continue;
      refs.push_back({e, t});
    }
  }
  if (refs.empty())
    throw DataError("data in " + o.data + " has no frame with a full " + std::to_string(K) +
                    "-frame history in the " + split + " episodes");
  if (o.max_frames > 0 && static_cast<size_t>(o.max_frames) < refs.size()) {
    std::vector<Ref> spread;
    for (long i = 0; i < o.max_frames; ++i)
      spread.push_back(refs[static_cast<size_t>(i) * refs.size() / o.max_frames]);
    refs = std::move(spread);
  }

  const size_t fv = set.frame_values();
  std::vector<uint8_t> history(fv * K);
  std::vector<const uint8_t*> ptr(K);
  for (int k = 0; k < K; ++k) ptr[k] = history.data() + k * fv;
  std::vector<DiagnosedFrame> frames;
  std::vector<uint32_t> masks;
  frames.reserve(refs.size());
  masks.reserve(refs.size());
  for (const Ref& r : refs) {
    const PackedEpisode& ep = set.episodes[r.e];
    for (int k = 0; k < K; ++k)
      set.planes255(r.e, r.t - (K - 1 - k) * stride, history.data() + k * fv);
    // The action executed one step before (residual's memory-only controller reads it).
    const float* previous =
        r.t >= 1 ? ep.action.data() + static_cast<size_t>(A) * (r.t - 1) : nullptr;
    policy.run(ptr.data(), ep.speed[r.t], ep.command[r.t], previous);
    DiagnosedFrame f;
    f.episode = r.e;
    f.t = r.t;
    if (speed_head) {
      f.label = {ep.speed[r.t + 1]};
    } else {
      const float* a = ep.action.data() + static_cast<size_t>(A) * r.t;
      f.label.assign(a, a + A);
    }
    f.prediction = policy.last_action();
    f.prediction.resize(f.label.size());
    frames.push_back(std::move(f));
    masks.push_back(driving ? situations_at(ep, r.t, set.dt, o.rules) : 1u << kAllFrames);
  }

  DiagnosisReport report = summarize_diagnosis(components, frames, masks, set.domain);
  report.checkpoint = o.checkpoint;
  report.data = o.data;
  report.method = ck.method;
  report.split = split;
  if (split == "val")
    for (int e : episodes) report.episodes.push_back(set.episodes[e].file);

  if (!o.plots.empty()) {
    std::vector<int> chosen = o.plot_episodes;
    if (chosen.empty())
      for (size_t i = 0; i < episodes.size() && i < 3; ++i) chosen.push_back(episodes[i]);
    std::filesystem::create_directories(o.plots);
    for (int e : chosen) {
      if (e < 0 || e >= static_cast<int>(set.episodes.size()))
        throw ConfigError("--plot-episodes: episode " + std::to_string(e) + " is not in " +
                          o.data + " (" + std::to_string(set.episodes.size()) + " episodes)");
      std::vector<DiagnosedFrame> ef;
      std::vector<uint32_t> em;
      for (size_t i = 0; i < frames.size(); ++i)
        if (frames[i].episode == e) {
          ef.push_back(frames[i]);
          em.push_back(masks[i]);
        }
      if (ef.empty())
        throw ConfigError("--plot-episodes: episode " + std::to_string(e) + " of " + o.data +
                          " is not among the compared frames (split " + split +
                          ", --max-frames); choose one of them or --split all");
      const std::string name = std::filesystem::path(set.episodes[e].file).stem().string();
      write_diagnosis_png(o.plots + "/" + name + ".png", components, ef, em);
    }
  }
  return report;
}

json diagnosis_json(const DiagnosisReport& r) {
  json situations = json::object();
  for (const SituationStats& s : r.situations) {
    json js = {{"count", s.count}};
    for (size_t a = 0; a < r.components.size(); ++a) {
      const ComponentStats& c = s.components[a];
      auto v = [&](double x) { return c.count > 0 ? json(x) : json(nullptr); };
      js[r.components[a]] = {{"label_mean", v(c.label_mean)}, {"label_sd", v(c.label_sd)},
                             {"pred_mean", v(c.pred_mean)},   {"pred_sd", v(c.pred_sd)},
                             {"mae", v(c.mae)},
                             {"r2", c.r2_defined ? json(c.r2) : json(nullptr)}};
    }
    situations[s.name] = js;
  }
  return {{"checkpoint", r.checkpoint}, {"data", r.data},     {"method", r.method},
          {"split", r.split},           {"domain", r.domain}, {"components", r.components},
          {"frames", r.frames},         {"episodes", r.episodes},
          {"situations", situations}};
}

std::string diagnosis_table(const DiagnosisReport& r) {
  char buf[256];
  std::string s;
  std::snprintf(buf, sizeof buf, "imitation diagnosis: %s on %s (%s episodes, %ld frames)\n",
                r.method.c_str(), r.data.c_str(), r.split.c_str(), r.frames);
  s += buf;
  s += "label and prediction: mean (sd); flat = the prediction varies less than a quarter of "
       "the label\n\n";
  std::snprintf(buf, sizeof buf, "%-17s %-12s %7s %17s %17s %7s %7s\n", "situation", "component",
                "frames", "label", "prediction", "mae", "r2");
  s += buf;
  for (const SituationStats& st : r.situations) {
    for (size_t a = 0; a < r.components.size(); ++a) {
      const ComponentStats& c = st.components[a];
      const char* name = a == 0 ? st.name.c_str() : "";
      if (c.count == 0) {
        std::snprintf(buf, sizeof buf, "%-17s %-12s %7ld %17s %17s %7s %7s\n", name,
                      r.components[a].c_str(), c.count, "-", "-", "-", "-");
      } else {
        char label[32], pred[32], r2[16];
        std::snprintf(label, sizeof label, "%.3f (%.3f)", c.label_mean, c.label_sd);
        std::snprintf(pred, sizeof pred, "%.3f (%.3f)", c.pred_mean, c.pred_sd);
        if (c.r2_defined)
          std::snprintf(r2, sizeof r2, "%.3f", c.r2);
        else
          std::snprintf(r2, sizeof r2, "-");
        const bool flat = c.label_sd > 1e-3 && c.pred_sd < 0.25 * c.label_sd;
        std::snprintf(buf, sizeof buf, "%-17s %-12s %7ld %17s %17s %7.3f %7s%s\n", name,
                      r.components[a].c_str(), c.count, label, pred, c.mae, r2,
                      flat ? "  flat" : "");
      }
      s += buf;
    }
  }
  return s;
}

void situation_colour(uint32_t mask, uint8_t rgb[3]) {
  static const uint8_t colours[kSituationCount][3] = {
      {230, 230, 230},  // all only: none of the situations
      {255, 140, 0},    // standing_free: orange (going is right)
      {50, 170, 50},    // starting: green
      {70, 130, 230},   // cruising: blue
      {220, 30, 30},    // slowing_red: red
      {160, 90, 200},   // slowing_other: purple
      {0, 190, 190},    // following: teal
      {110, 110, 110},  // standing_blocked: grey
  };
  int pick = kAllFrames;
  for (int s = 1; s < kSituationCount; ++s)
    if ((mask >> s) & 1u) {
      pick = s;
      break;
    }
  std::copy_n(colours[pick], 3, rgb);
}

void write_diagnosis_png(const std::string& path, const std::vector<std::string>& components,
                         const std::vector<DiagnosedFrame>& frames,
                         const std::vector<uint32_t>& situations) {
  constexpr int kStrip = 12, kPanel = 120, kGap = 6, kMargin = 4;
  const int n = static_cast<int>(frames.size());
  const int A = static_cast<int>(components.size());
  const int W = std::max(64, n + 2 * kMargin);
  const int H = kStrip + A * (kPanel + kGap) + kMargin;
  std::vector<uint8_t> img(static_cast<size_t>(W) * H * 3, 255);
  const uint8_t black[3] = {0, 0, 0}, red[3] = {220, 20, 20}, axis[3] = {200, 200, 200};
  for (int i = 0; i < n; ++i) {
    uint8_t rgb[3];
    situation_colour(situations[i], rgb);
    for (int y = 0; y < kStrip - 2; ++y) set_pixel(img, W, H, kMargin + i, y, rgb);
  }
  for (int a = 0; a < A; ++a) {
    // Each panel spans the range of its label and prediction (at least 0..1 for actions).
    double lo = 0, hi = components[a] == "target_speed" ? 0.0 : 1.0;
    if (components[a] == "steer" || components[a][0] == 'a') lo = -1;
    for (const DiagnosedFrame& f : frames) {
      lo = std::min({lo, double(f.label[a]), double(f.prediction[a])});
      hi = std::max({hi, double(f.label[a]), double(f.prediction[a])});
    }
    if (hi - lo < 1e-6) hi = lo + 1;
    const int top = kStrip + a * (kPanel + kGap);
    auto y_of = [&](double v) {
      return top + static_cast<int>(std::lround((hi - v) / (hi - lo) * (kPanel - 1)));
    };
    for (int x = kMargin; x < kMargin + n; ++x) {
      set_pixel(img, W, H, x, top, axis);
      set_pixel(img, W, H, x, top + kPanel - 1, axis);
      if (lo < 0 && hi > 0) set_pixel(img, W, H, x, y_of(0.0), axis);
    }
    for (int series = 0; series < 2; ++series)
      for (int i = 1; i < n; ++i) {
        auto value = [&](int k) {
          return series == 0 ? frames[k].label[a] : frames[k].prediction[a];
        };
        draw_line(img, W, H, kMargin + i - 1, y_of(value(i - 1)), kMargin + i, y_of(value(i)),
                  series == 0 ? black : red);
      }
  }
  write_png_rgb(path, img, W, H);
}

}  // namespace cd
