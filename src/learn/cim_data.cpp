#include "learn/cim_data.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace cd {

namespace {
constexpr int kOut = 64;  // the VAE's input size (nn/beta_vae.hpp kVaeSize)

// Area resampling: output cell i covers source [i*n/64, (i+1)*n/64), at least one pixel.
void ranges(int n, std::vector<int>& lo, std::vector<int>& hi) {
  lo.resize(kOut);
  hi.resize(kOut);
  for (int i = 0; i < kOut; ++i) {
    lo[i] = std::min(n - 1, i * n / kOut);
    hi[i] = std::max(lo[i] + 1, (i + 1) * n / kOut);
  }
}

template <class On>
void resample(const CimView& v, On on, float* out) {
  if (v.height == kOut && v.width == kOut) {
    for (int i = 0; i < kOut * kOut; ++i) out[i] = on(static_cast<size_t>(i)) ? 1.0f : 0.0f;
    return;
  }
  for (int y = 0; y < kOut; ++y)
    for (int x = 0; x < kOut; ++x) {
      int count = 0, set = 0;
      for (int sy = v.y0[y]; sy < v.y1[y]; ++sy)
        for (int sx = v.x0[x]; sx < v.x1[x]; ++sx) {
          ++count;
          set += on(static_cast<size_t>(sy) * v.width + sx) ? 1 : 0;
        }
      out[y * kOut + x] = static_cast<float>(set) / static_cast<float>(count);
    }
}

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}
}  // namespace

CimView resolve_view(const std::string& view, const std::vector<std::string>& channel_names,
                     int height, int width) {
  CimView v;
  v.channel_count = static_cast<int>(channel_names.size());
  v.height = height;
  v.width = width;
  size_t start = 0;
  while (start <= view.size()) {
    size_t plus = view.find('+', start);
    std::string name = view.substr(start, plus == std::string::npos ? std::string::npos : plus - start);
    auto it = std::find(channel_names.begin(), channel_names.end(), name);
    if (name.empty() || it == channel_names.end())
      throw ConfigError("vae.view: no BEV channel '" + name + "' in the data (channels: " +
                        join(channel_names) + ")");
    int c = static_cast<int>(it - channel_names.begin());
    if (c >= 8) throw ConfigError("vae.view: channel '" + name + "' beyond the 8 packed channels");
    if (std::find(v.channels.begin(), v.channels.end(), c) == v.channels.end()) v.channels.push_back(c);
    v.mask |= static_cast<uint8_t>(1u << c);
    if (plus == std::string::npos) break;
    start = plus + 1;
  }
  ranges(height, v.y0, v.y1);
  ranges(width, v.x0, v.x1);
  return v;
}

void view_from_packed(const CimView& v, const uint8_t* packed, float* out) {
  resample(v, [&](size_t i) { return (packed[i] & v.mask) != 0; }, out);
}

void view_from_planes(const CimView& v, const uint8_t* planes, float* out) {
  const size_t pixels = static_cast<size_t>(v.height) * v.width;
  resample(v, [&](size_t i) {
    for (int c : v.channels)
      if (planes[static_cast<size_t>(c) * pixels + i]) return true;
    return false;
  }, out);
}

CauseSelection select_causes(const std::vector<std::vector<double>>& speed,
                             const std::vector<std::vector<std::vector<double>>>& latents,
                             const CimSettings& cim, bool use_all) {
  CauseSelection sel;
  const int m = static_cast<int>(latents.size());
  if (m == 0) throw ConfigError("cause selection: no latent variables");
  std::vector<double> p(m);
  sel.tests.resize(m);
  for (int i = 0; i < m; ++i) {
    sel.tests[i].index = i;
    sel.tests[i].test = granger_f_test(speed, latents[i], cim.lags);
    p[i] = sel.tests[i].test.p_value;
  }
  sel.rows = sel.tests[0].test.rows;
  const std::vector<double> adj = adjust_p_values(p, cim.correction);
  std::vector<int> significant;
  for (int i = 0; i < m; ++i) {
    sel.tests[i].p_adjusted = adj[i];
    sel.tests[i].significant = adj[i] <= cim.alpha;
    if (sel.tests[i].significant) significant.push_back(i);
  }
  sel.significant = static_cast<int>(significant.size());

  // Threshold on the raw p-values (for the chart): alpha, alpha/m, or the BH cut-off
  // k*alpha/m of the largest rank k with p_(k) <= k*alpha/m (alpha/m when there is none).
  if (cim.correction == "none") {
    sel.threshold_p = cim.alpha;
  } else if (cim.correction == "bonferroni") {
    sel.threshold_p = cim.alpha / m;
  } else {
    std::vector<double> sorted = p;
    std::sort(sorted.begin(), sorted.end());
    sel.threshold_p = cim.alpha / m;
    for (int k = m; k >= 1; --k)
      if (sorted[k - 1] <= k * cim.alpha / m) {
        sel.threshold_p = k * cim.alpha / m;
        break;
      }
  }

  auto better = [&](int a, int b, const std::vector<double>& key) {
    if (key[a] != key[b]) return key[a] < key[b];
    if (sel.tests[a].test.f_stat != sel.tests[b].test.f_stat)
      return sel.tests[a].test.f_stat > sel.tests[b].test.f_stat;
    return a < b;
  };
  if (significant.empty()) {
    std::vector<int> all(m);
    std::iota(all.begin(), all.end(), 0);
    sel.ranked = {*std::min_element(all.begin(), all.end(),
                                    [&](int a, int b) { return better(a, b, p); })};
    sel.fallback = true;
  } else {
    std::sort(significant.begin(), significant.end(),
              [&](int a, int b) { return better(a, b, adj); });
    if (cim.max_causes > 0 && static_cast<int>(significant.size()) > cim.max_causes) {
      significant.resize(cim.max_causes);
      sel.capped = true;
    }
    sel.ranked = significant;
    std::sort(sel.ranked.begin(), sel.ranked.end());
  }
  if (use_all) {
    sel.selected.resize(m);
    std::iota(sel.selected.begin(), sel.selected.end(), 0);
  } else {
    sel.selected = sel.ranked;
  }
  for (int i : sel.selected) sel.tests[i].selected = true;
  return sel;
}

const std::vector<std::string>& ground_truth_names() {
  static const std::vector<std::string> names = {"lead_distance", "lead_present", "red_light",
                                                 "path_free", "ped_on_path"};
  return names;
}

double ground_truth_value(const PackedEpisode& ep, const std::string& name, int t) {
  const double nan = std::nan("");
  auto get = [&](const char* key) -> const std::vector<float>* {
    auto it = ep.causes.find(key);
    if (it == ep.causes.end() || static_cast<int>(it->second.size()) <= t) return nullptr;
    return &it->second;
  };
  if (name == "lead_distance") {
    const auto* d = get("lead_distance");
    const auto* present = get("lead_present");
    if (!d) return nan;
    if (present && (*present)[t] == 0) return 60.0;
    double v = (*d)[t];
    return std::isfinite(v) ? std::min(v, 60.0) : 60.0;
  }
  if (name == "red_light") {
    const auto* s = get("tl_state");
    const auto* d = get("tl_distance");
    if (!s || !d) return nan;
    const int state = static_cast<int>(std::lround((*s)[t]));
    return (state == 1 || state == 2) && (*d)[t] < 30 ? 1.0 : 0.0;
  }
  if (name == "path_free") {
    const auto* v = get("path_free");
    if (v) return (*v)[t];
    if (static_cast<int>(ep.path_free.size()) > t) return ep.path_free[t];
    return nan;
  }
  const auto* v = get(name.c_str());
  return v ? static_cast<double>((*v)[t]) : nan;
}

double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = std::min(a.size(), b.size());
  if (n < 2) return std::nan("");
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= n;
  mb /= n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  if (saa <= 0 || sbb <= 0 || !std::isfinite(sab)) return std::nan("");
  return sab / std::sqrt(saa * sbb);
}

bool CimRunInfo::has_stage(const std::string& stage) const {
  return std::find(stages.begin(), stages.end(), stage) != stages.end();
}

std::optional<CimRunInfo> read_cim_run(const std::string& dir) {
  const std::string path = dir + "/" + kCimRunJson;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  CimRunInfo r;
  r.dir = dir;
  try {
    r.record = nlohmann::json::parse(read_file_bytes(path));
    const auto& j = r.record;
    r.method = j.at("method").get<std::string>();
    r.data_dir = j.at("data_dir").get<std::string>();
    r.init = j.value("init", "");
    r.vae_from = j.value("vae_from", "");
    r.stages = j.at("stages").get<std::vector<std::string>>();
    const auto& in = j.at("input");
    r.channels = in.at("channels").get<int>();
    r.height = in.at("height").get<int>();
    r.width = in.at("width").get<int>();
    r.channel_names = in.at("channel_names").get<std::vector<std::string>>();
    const auto& v = j.at("settings").at("vae");
    r.vae.view = v.at("view").get<std::string>();
    r.vae.latents = v.at("latents").get<int>();
    r.vae.beta = v.at("beta").get<double>();
    r.vae.epochs = v.at("epochs").get<int>();
    r.vae.batch_size = v.at("batch_size").get<int>();
    r.vae.lr = v.at("lr").get<double>();
    r.vae.max_frames = v.at("max_frames").get<long>();
    const auto& c = j.at("settings").at("cim");
    r.cim.lags = c.at("lags").get<int>();
    r.cim.alpha = c.at("alpha").get<double>();
    r.cim.correction = c.at("correction").get<std::string>();
    r.cim.max_causes = c.at("max_causes").get<int>();
    r.cim.series_stride = c.at("series_stride").get<int>();
    r.cim.history = c.at("history").get<int>();
    r.cim.history_stride = c.at("history_stride").get<int>();
    r.cim.encoder_units = c.at("encoder_units").get<int>();
    r.cim.mlp_encoder_units = c.at("mlp_encoder_units").get<int>();
    r.cim.hidden = c.at("hidden").get<int>();
    r.cim.epochs = c.at("epochs").get<int>();
    r.cim.batch_size = c.at("batch_size").get<int>();
    r.cim.lr = c.at("lr").get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw DataError(path + " is damaged (" + e.what() + "): delete the folder to start over");
  }
  return r;
}

CimRunInfo require_cim_run(const std::string& dir, const std::string& method,
                           const std::vector<std::string>& stages, const std::string& role) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw ConfigError(role + " " + dir + ": no such run folder");
  std::optional<CimRunInfo> r = read_cim_run(dir);
  if (!r)
    throw ConfigError(role + " " + dir + " is not a cim run folder (no " + kCimRunJson +
                      "; train it with causaldrive train --method cim ...)");
  if (r->method.rfind("cim", 0) != 0 || (!method.empty() && r->method != method))
    throw ConfigError(role + " " + dir + " holds a run of method '" + r->method + "', not '" +
                      (method.empty() ? std::string("cim*") : method) + "'");
  for (const auto& st : stages)
    if (!r->has_stage(st))
      throw ConfigError(role + " " + dir + " is unfinished (stage '" + st +
                        "' not done): finish it with causaldrive train first");
  return *r;
}

nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace cd
