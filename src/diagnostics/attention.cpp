#include "diagnostics/attention.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/png.hpp"
#include "datasets/episode_set.hpp"
#include "runs/checkpoint.hpp"
#include "sense/bev.hpp"  // kBevChannelCount
#include "sense/bev_colour.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kAttentionJson = "attention.json";

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// The method a run folder's other records (dim.json, cim's run.json) name, "" when none.
std::string recorded_method(const std::string& dir) {
  for (const char* name : {"dim.json", "run.json"}) {
    try {
      json j = json::parse(read_file_bytes(dir + "/" + name));
      if (j.is_object() && j.contains("method") && j["method"].is_string())
        return j["method"].get<std::string>();
    } catch (const std::exception&) {
      // no such record, or not one: the checkpoint's own checks decide
    }
  }
  return "";
}

[[noreturn]] void refuse_method(const std::string& dir, const std::string& method) {
  throw ConfigError("attention maps need an image policy (" + join(policy_runner_methods()) +
                    "); " + dir + " holds a run of '" + method + "'");
}

// Inferno-like colour map: 0 black, through purple and orange, 1 pale yellow.
std::array<double, 3> heat(double v) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {{
      {0, 0, 4}, {87, 16, 110}, {188, 55, 84}, {249, 142, 9}, {252, 255, 164}}};
  v = std::clamp(v, 0.0, 1.0) * (kStops.size() - 1);
  const size_t i = std::min(static_cast<size_t>(v), kStops.size() - 2);
  const double f = v - static_cast<double>(i);
  std::array<double, 3> c;
  for (int k = 0; k < 3; ++k) c[k] = kStops[i][k] + f * (kStops[i + 1][k] - kStops[i][k]);
  return c;
}

uint8_t byte(double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 255.0))); }

json shares_json(const std::vector<std::string>& names, const std::vector<double>& v) {
  json j = json::object();
  for (size_t i = 0; i < names.size() && i < v.size(); ++i) j[names[i]] = v[i];
  return j;
}

}  // namespace

const std::vector<std::string>& attention_selections() {
  static const std::vector<std::string> names = {"stopped", "all", "light"};
  return names;
}

std::vector<float> resize_bilinear(const std::vector<float>& map, int h, int w, int height,
                                   int width) {
  std::vector<float> out(static_cast<size_t>(height) * width);
  // Source coordinate of an output pixel centre (align_corners = false), clamped at 0; the
  // upper neighbour is clamped to the last row / column.
  auto source = [](int dst, int in, int outn, int& i0, int& i1, float& frac) {
    const float scale = static_cast<float>(in) / static_cast<float>(outn);
    float s = scale * (static_cast<float>(dst) + 0.5f) - 0.5f;
    if (s < 0) s = 0;
    i0 = std::min(static_cast<int>(s), in - 1);
    i1 = std::min(i0 + 1, in - 1);
    frac = s - static_cast<float>(i0);
  };
  for (int y = 0; y < height; ++y) {
    int y0, y1;
    float fy;
    source(y, h, height, y0, y1, fy);
    for (int x = 0; x < width; ++x) {
      int x0, x1;
      float fx;
      source(x, w, width, x0, x1, fx);
      const float top = (1 - fx) * map[y0 * w + x0] + fx * map[y0 * w + x1];
      const float bottom = (1 - fx) * map[y1 * w + x0] + fx * map[y1 * w + x1];
      out[static_cast<size_t>(y) * width + x] = (1 - fy) * top + fy * bottom;
    }
  }
  return out;
}

std::vector<float> grad_cam(const FeatureMapGradient& g, int height, int width, double* raw_max) {
  const int C = g.channels, h = g.height, w = g.width;
  const size_t plane = static_cast<size_t>(h) * w;
  if (C < 1 || h < 1 || w < 1 || g.activation.size() != C * plane ||
      g.gradient.size() != C * plane)
    throw Error("grad_cam: a feature map and its gradient of " + std::to_string(C) + " x " +
                std::to_string(h) + " x " + std::to_string(w) + " values expected");
  std::vector<double> cam(plane, 0.0);
  for (int k = 0; k < C; ++k) {
    const float* grad = g.gradient.data() + k * plane;
    const float* act = g.activation.data() + k * plane;
    double weight = 0;
    for (size_t i = 0; i < plane; ++i) weight += grad[i];
    weight /= static_cast<double>(plane);
    for (size_t i = 0; i < plane; ++i) cam[i] += weight * act[i];
  }
  std::vector<float> small(plane);
  double peak = 0;
  for (size_t i = 0; i < plane; ++i) {
    small[i] = static_cast<float>(std::max(0.0, cam[i]));
    peak = std::max(peak, static_cast<double>(small[i]));
  }
  if (raw_max) *raw_max = peak;
  std::vector<float> map = resize_bilinear(small, h, w, height, width);
  const float top = map.empty() ? 0.0f : *std::max_element(map.begin(), map.end());
  if (top > 0)
    for (float& v : map) v /= top;
  else
    std::fill(map.begin(), map.end(), 0.0f);
  return map;
}

std::vector<int> top_channel(const unsigned char* frame, int channels, int height, int width) {
  const size_t plane = static_cast<size_t>(height) * width;
  std::vector<int> top(plane, channels);
  for (int c = 0; c < channels; ++c)
    for (size_t i = 0; i < plane; ++i)
      if (frame[c * plane + i]) top[i] = c;
  return top;
}

std::vector<unsigned char> attention_grid(const unsigned char* frame, int channels, int height,
                                          int width, const std::vector<float>& map, int scale,
                                          int* grid_width, int* grid_height, bool rgb) {
  const int pw = width * scale, ph = height * scale, sep = kAttentionSeparator;
  const int gw = 3 * pw + 2 * sep;
  const std::vector<uint8_t> colour = frame_picture(frame, channels, height, width, rgb);
  std::vector<unsigned char> grid(static_cast<size_t>(gw) * ph * 3, 255);  // white separators
  for (int y = 0; y < ph; ++y)
    for (int x = 0; x < pw; ++x) {
      const size_t src = static_cast<size_t>(y / scale) * width + x / scale;
      const double v = map[src];
      const std::array<double, 3> hc = heat(v);
      const double alpha = 0.7 * v;
      for (int panel = 0; panel < 3; ++panel) {
        unsigned char* o = &grid[(static_cast<size_t>(y) * gw + panel * (pw + sep) + x) * 3];
        for (int k = 0; k < 3; ++k) {
          const double f = colour[src * 3 + k];
          o[k] = panel == 0   ? colour[src * 3 + k]
                 : panel == 1 ? byte(hc[k])
                              : byte((1 - alpha) * f + alpha * hc[k]);
        }
      }
    }
  *grid_width = gw;
  *grid_height = ph;
  return grid;
}

AttentionReport run_attention(const AttentionOptions& o) {
  if (o.frames < 1)
    throw ConfigError("--frames must be at least 1 (got " + std::to_string(o.frames) + ")");
  const auto& selections = attention_selections();
  if (std::find(selections.begin(), selections.end(), o.select) == selections.end())
    throw ConfigError("unknown --select '" + o.select + "' (known: " + join(selections) + ")");
  if (o.scale < 1 || o.scale > 16)
    throw ConfigError("--scale must be in [1, 16] (got " + std::to_string(o.scale) + ")");
  if (o.out.empty()) throw ConfigError("attention needs an output folder (--out)");

  // An image policy's folder: refuse the runs of other methods with the list of those it takes.
  const std::optional<Checkpoint> found = read_checkpoint(o.checkpoint);
  if (!found) {
    const std::string other = recorded_method(o.checkpoint);
    if (!other.empty()) refuse_method(o.checkpoint, other);
  } else {
    if (!is_policy_runner_method(found->method))
      refuse_method(o.checkpoint, found->method);
  }
  set_torch_threads(1);
  PolicyRunner policy(o.checkpoint);
  const Checkpoint& ck = policy.checkpoint();
  const int K = policy.history(), stride = policy.stride();
  EpisodeSet set = load_episode_set(o.data);
  const InputFormat& in = ck.input;
  if (set.channels != in.channels || set.height != in.height || set.width != in.width ||
      set.action_dim != in.action_dim)
    throw DataError("data in " + o.data + " has " + std::to_string(set.channels) + "x" +
                    std::to_string(set.height) + "x" + std::to_string(set.width) +
                    " frames and " + std::to_string(set.action_dim) +
                    " action components, the checkpoint was trained on " +
                    std::to_string(in.channels) + "x" + std::to_string(in.height) + "x" +
                    std::to_string(in.width) + " and " + std::to_string(in.action_dim));
  // RGB frames (the front camera's, MuJoCo-Image's) are drawn in their own colours and have no
  // layers to split the attention by.
  const bool rgb = set.layout == FrameLayout::Bytes;
  if (!rgb && set.channels > kBevChannelCount)
    throw DataError("data in " + o.data + " has " + std::to_string(set.channels) +
                    " channels; attention maps are drawn for at most " +
                    std::to_string(int(kBevChannelCount)));

  AttentionReport r;
  r.checkpoint = o.checkpoint;
  r.data = o.data;
  r.out = o.out;
  r.method = ck.method;
  r.output = policy.target_speed_head() ? "target_speed" : "throttle_minus_brake";
  r.select = o.select;
  r.history = K;
  r.stride = stride;
  if (!rgb) {
    r.channels = set.channel_names;
    r.channels.resize(set.channels);
    for (int c = 0; c < set.channels; ++c)
      if (r.channels[c].empty()) r.channels[c] = "channel_" + std::to_string(c);
    r.channels.push_back("none");
  }

  struct Candidate {
    int e, t;
  };
  std::vector<Candidate> chosen;
  const int first = (K - 1) * stride;
  for (int e = 0; e < static_cast<int>(set.episodes.size()); ++e) {
    const PackedEpisode& ep = set.episodes[e];
    const std::vector<float>* tl_state = nullptr;
    const std::vector<float>* tl_distance = nullptr;
    if (o.select == "light") {
      auto s = ep.causes.find("tl_state"), d = ep.causes.find("tl_distance");
      if (s == ep.causes.end() || d == ep.causes.end())
        throw DataError("episode file " + o.data + "/" + ep.file +
                        " has no causes/tl_state and tl_distance (record the data with "
                        "`causaldrive collect`, or use --select all)");
      tl_state = &s->second;
      tl_distance = &d->second;
    }
    for (int t = first; t < ep.frames; ++t) {
      bool take = true;
      if (o.select == "stopped") take = ep.speed[t] < o.stopped_below;
      if (tl_state) take = (*tl_state)[t] != 0 && (*tl_distance)[t] < o.light_near;
      if (take) chosen.push_back({e, t});
    }
  }
  r.candidates = static_cast<long>(chosen.size());
  if (chosen.empty())
    throw DataError("no frame of " + o.data + " fits --select " + o.select +
                    " with a full history of " + std::to_string(K) + " frames");
  if (static_cast<size_t>(o.frames) < chosen.size()) {
    std::vector<Candidate> spread;
    for (long i = 0; i < o.frames; ++i)
      spread.push_back(chosen[static_cast<size_t>(i) * chosen.size() / o.frames]);
    chosen = spread;
  }

  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (!fs::is_directory(o.out))
    throw IoError("cannot create the output folder " + o.out);
  // The grids of an earlier run into this folder (attention_NNN.png) would outlive its
  // attention.json: remove them first.
  remove_stale_temporaries(o.out);
  for (const auto& entry : fs::directory_iterator(o.out, ec)) {
    const std::string n = entry.path().filename().string();
    if (n.size() > 14 && n.starts_with("attention_") && n.ends_with(".png") &&
        std::all_of(n.begin() + 10, n.end() - 4, [](char ch) { return ch >= '0' && ch <= '9'; }))
      fs::remove(entry.path(), ec);
  }

  const size_t fv = set.frame_values();
  const int C = set.channels, H = set.height, W = set.width, A = set.action_dim;
  const size_t plane = set.frame_pixels();
  std::vector<uint8_t> history(fv * K);
  std::vector<const uint8_t*> ptr(K);
  for (int k = 0; k < K; ++k) ptr[k] = history.data() + k * fv;
  const size_t groups = r.channels.size();
  r.mean_attention_share.assign(groups, 0.0);
  r.mean_pixel_share.assign(groups, 0.0);
  for (size_t i = 0; i < chosen.size(); ++i) {
    const Candidate& c = chosen[i];
    const PackedEpisode& ep = set.episodes[c.e];
    for (int k = 0; k < K; ++k) set.planes255(c.e, c.t - (K - 1 - k) * stride, history.data() + k * fv);
    const float* previous = c.t >= 1 ? ep.action.data() + static_cast<size_t>(c.t - 1) * A : nullptr;
    FeatureMapGradient g;
    const PolicyStep step =
        policy.run_with_gradient(ptr.data(), ep.speed[c.t], ep.command[c.t], previous, g);
    AttentionFrame f;
    const std::vector<float> map = grad_cam(g, H, W, &f.map_max);
    const uint8_t* current = ptr[K - 1];

    char name[48];
    std::snprintf(name, sizeof name, "attention_%03zu.png", i);
    f.png = name;
    f.episode = ep.file;
    f.t = c.t;
    f.speed = ep.speed[c.t];
    f.command = ep.command[c.t];
    if (auto s = ep.causes.find("tl_state"); s != ep.causes.end()) f.tl_state = s->second[c.t];
    if (auto d = ep.causes.find("tl_distance"); d != ep.causes.end())
      f.tl_distance = d->second[c.t];
    f.output = step.scalar();
    f.action = policy.last_action();
    f.module = g.module;
    if (i == 0) {
      r.map_channels = g.channels;
      r.map_height = g.height;
      r.map_width = g.width;
    }

    std::vector<double> mass(groups, 0.0), pixels(groups, 0.0);
    double total = 0;
    if (groups > 0) {  // the BEV: the attention on each layer (the one drawn on top)
      const std::vector<int> top = top_channel(current, C, H, W);
      for (size_t p = 0; p < plane; ++p) {
        mass[top[p]] += map[p];
        pixels[top[p]] += 1;
        total += map[p];
      }
    } else {
      for (size_t p = 0; p < plane; ++p) total += map[p];
    }
    f.attention_share.assign(groups, 0.0);
    f.pixel_share.assign(groups, 0.0);
    for (size_t k = 0; k < groups; ++k) {
      if (total > 0) f.attention_share[k] = mass[k] / total;
      f.pixel_share[k] = pixels[k] / static_cast<double>(plane);
    }
    if (total > 0) {
      ++r.attended_frames;
      for (size_t k = 0; k < groups; ++k) {
        r.mean_attention_share[k] += f.attention_share[k];
        r.mean_pixel_share[k] += f.pixel_share[k];
      }
    }

    int gw = 0, gh = 0;
    const std::vector<unsigned char> grid =
        attention_grid(current, C, H, W, map, o.scale, &gw, &gh, rgb);
    write_png_rgb(o.out + "/" + f.png, grid, gw, gh);
    r.frames.push_back(std::move(f));
  }
  if (r.attended_frames > 0)
    for (size_t k = 0; k < groups; ++k) {
      r.mean_attention_share[k] /= static_cast<double>(r.attended_frames);
      r.mean_pixel_share[k] /= static_cast<double>(r.attended_frames);
    }
  write_file_atomic(o.out + "/" + kAttentionJson, attention_report_json(r).dump(2) + "\n");
  return r;
}

json attention_report_json(const AttentionReport& r) {
  json frames = json::array();
  for (const AttentionFrame& f : r.frames) {
    auto series = [](double v) { return v < 0 ? json(nullptr) : json(v); };
    frames.push_back({{"png", f.png},
                      {"episode", f.episode},
                      {"t", f.t},
                      {"speed", f.speed},
                      {"command", f.command},
                      {"tl_state", series(f.tl_state)},
                      {"tl_distance", series(f.tl_distance)},
                      {"output", f.output},
                      {"action", f.action},
                      {"module", f.module},
                      {"map_max", f.map_max},
                      {"attention_share", shares_json(r.channels, f.attention_share)},
                      {"pixel_share", shares_json(r.channels, f.pixel_share)}});
  }
  return {{"checkpoint", r.checkpoint},
          {"data", r.data},
          {"method", r.method},
          {"history", r.history},
          {"history_stride", r.stride},
          {"output", r.output},
          {"select", r.select},
          {"feature_map", {r.map_channels, r.map_height, r.map_width}},
          {"channels", r.channels},
          {"candidates", r.candidates},
          {"frames", frames},
          {"mean",
           {{"frames", r.attended_frames},
            {"attention_share", shares_json(r.channels, r.mean_attention_share)},
            {"pixel_share", shares_json(r.channels, r.mean_pixel_share)}}}};
}

std::string attention_report_table(const AttentionReport& r) {
  char buf[512];
  std::string s;
  std::snprintf(buf, sizeof buf,
                "attention (Grad-CAM): %s (history %d, stride %d) on %s\n"
                "output: %s; frames: %zu of %ld (--select %s), %ld with a non-zero map\n"
                "feature map %d x %d x %d; PNGs and attention.json in %s\n\n",
                r.method.c_str(), r.history, r.stride, r.data.c_str(),
                r.output == "target_speed" ? "target speed (m/s)" : "throttle - brake",
                r.frames.size(), r.candidates, r.select.c_str(), r.attended_frames,
                r.map_channels, r.map_height, r.map_width, r.out.c_str());
  s += buf;
  std::snprintf(buf, sizeof buf, "%-14s %10s %10s\n", "channel", "attention", "pixels");
  s += buf;
  for (size_t k = 0; k < r.channels.size(); ++k) {
    std::snprintf(buf, sizeof buf, "%-14s %10.3f %10.3f\n", r.channels[k].c_str(),
                  r.mean_attention_share[k], r.mean_pixel_share[k]);
    s += buf;
  }
  return s;
}

}  // namespace cd
