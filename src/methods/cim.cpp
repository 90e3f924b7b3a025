// The cim family of seed 000 (cim, cim-mlp, cim-entangled): beta-VAE perception -> Granger
// cause selection -> causal speed predictor -> speed PID. The pipeline, stage by stage, into
// one run folder (runs/cim_run.hpp):
//
//   run.json                 commit record: method, settings, data folder, input format, init /
//                            vae_from, finished stages, figures of each stage
//   vae.pt, vae_metrics.jsonl           stage "vae": the beta-VAE (or a copy of another run's)
//   series.csv                          stage "series": segment, speed, z0..z{L-1} every
//                                       cim.series_stride-th frame of the training episodes,
//                                       cut at injected noise (what `causaldrive granger
//                                       --input RUN` reads)
//   causes.json                         stage "causes": Granger tests, the cim.selection rule's
//                                       picks, the three rules compared, ground truth
//   predictor.pt, predictor_metrics.jsonl  stage "predictor": best validation epoch
//   traversal.png, granger.png          stage "pictures" (diagnostics/cim_pictures.hpp)
//
// Every file is written atomically before run.json names its stage as done, so a rerun skips
// finished stages and redoes an interrupted one from its start. A few-shot run (--init RUN)
// copies RUN's vae.pt and causes.json (no series, no new selection) and fine-tunes RUN's
// predictor for cim.fewshot_steps Adam steps on train.max_samples labels drawn from every
// episode of the new data: those labels are all it uses (no validation split, the last
// weights are kept). Samples whose next speed was driven by injected noise are never labels.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>

#include <ATen/Parallel.h>
#include <nlohmann/json.hpp>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "agents/agent.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"
#include "causal/cause_selection.hpp"
#include "control/pid.hpp"
#include "datasets/episode_set.hpp"
#include "datasets/ground_truth.hpp"
#include "datasets/split.hpp"
#include "diagnostics/cim_pictures.hpp"
#include "inference/policy_runner.hpp"
#include "methods/method.hpp"
#include "runs/dim_run.hpp"
#include "nn/beta_vae.hpp"
#include "nn/policy_net.hpp"
#include "nn/speed_predictor.hpp"
#include "runs/cim_run.hpp"
#include "runs/record.hpp"
#include "sense/grey_view.hpp"
#include "train/loop.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr uint64_t kVaeSubsetStream = 0xc1a0001;
constexpr uint64_t kVaeOrderStream = 0xc1a0002;
constexpr uint64_t kVaeNoiseStream = 0xc1a0003;
constexpr uint64_t kPredSubsetStream = 0xc1a0004;
constexpr uint64_t kPredOrderStream = 0xc1a0005;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void say(bool quiet, const std::string& line, FILE* to = stdout) {
  if (quiet && to == stdout) return;
  std::fprintf(to, "%s\n", line.c_str());
  std::fflush(to);
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

// Settings a rerun into the same folder must share: everything the stages read ([vae], [cim],
// [bev] and these [train] keys).
bool may_differ(const std::string& table, const std::string& key) {
  return table == "train" && !(key == "seed" || key == "val_fraction" || key == "max_samples" ||
                                key == "loss" || key == "flush_denormals");
}

void check_same_vae(const CimRunInfo& src, const VaeSettings& want, const std::string& method,
                    const std::string& role) {
  auto bad = [&](const std::string& what) {
    throw ConfigError(role + " " + src.dir + ": its VAE has " + what + " (method '" + method +
                      "' trains with these settings): use a run with a matching VAE");
  };
  if (src.vae.beta != want.beta)
    bad("vae.beta " + fmt("%g", src.vae.beta) + ", this run needs " + fmt("%g", want.beta));
  if (src.vae.latents != want.latents)
    bad("vae.latents " + std::to_string(src.vae.latents) + ", this run needs " +
        std::to_string(want.latents));
  if (src.vae.view != want.view) bad("vae.view '" + src.vae.view + "', this run needs '" + want.view + "'");
}

void check_same_input(const CimRunInfo& src, const EpisodeSet& eps, const std::string& role) {
  if (src.height != eps.height || src.width != eps.width || src.channel_names != eps.channel_names)
    throw ConfigError(role + " " + src.dir + " was trained on " + std::to_string(src.channels) +
                      "x" + std::to_string(src.height) + "x" + std::to_string(src.width) +
                      " BEV frames (other channels or size than " + eps.dir + ")");
}

// mu of every frame, frame-major: row (offset[e] + t) holds latents values.
struct Encoded {
  int latents = 0;
  std::vector<long> offset;  // per episode
  std::vector<float> mu;
  std::vector<std::vector<double>> kl_sum;  // per episode: each latent's KL summed over its frames
  std::vector<long> encoded;                // per episode: its frames encoded
  const float* at(int e, int t) const {
    return mu.data() + (offset[e] + t) * static_cast<long>(latents);
  }
};

// The grey views of frames[rows[i]] (frames[i] when rows is null), i < n, into out.
void fill_views(const EpisodeSet& eps, const GreyView& view, const std::pair<int, int>* frames,
                const uint32_t* rows, int64_t n, float* out) {
  const int plane = kVaeSize * kVaeSize;
  at::parallel_for(0, n, 16, [&](int64_t lo, int64_t hi) {
    for (int64_t i = lo; i < hi; ++i) {
      const auto [e, t] = frames[rows ? rows[i] : i];
      view_from_packed(view, eps.episodes[e].frame_data.data() + static_cast<size_t>(t) * eps.frame_pixels(),
                       out + i * plane);
    }
  });
}

// mu of frames[i] at row i, and each latent's KL summed per episode (eval mode, no gradient).
Encoded encode_frames(BetaVae& vae, const EpisodeSet& eps, const GreyView& view,
                      const std::vector<std::pair<int, int>>& frames, const torch::Device& device,
                      bool quiet) {
  torch::NoGradGuard no_grad;
  vae->eval();
  Encoded enc;
  enc.latents = vae->latents();
  enc.mu.resize(frames.size() * enc.latents);
  enc.kl_sum.assign(eps.episodes.size(), std::vector<double>(static_cast<size_t>(enc.latents), 0.0));
  enc.encoded.assign(eps.episodes.size(), 0);
  for (const auto& f : frames) ++enc.encoded[static_cast<size_t>(f.first)];
  constexpr int B = 512;
  torch::Tensor batch = torch::empty({B, 1, kVaeSize, kVaeSize});
  std::optional<Progress> progress;
  if (!quiet) progress.emplace("encode frames", static_cast<long>(frames.size()));
  for (size_t begin = 0; begin < frames.size(); begin += B) {
    const int64_t n = std::min<int64_t>(B, static_cast<int64_t>(frames.size() - begin));
    fill_views(eps, view, frames.data() + begin, nullptr, n, batch.data_ptr<float>());
    auto [mu_d, logvar] = vae->encode(batch.narrow(0, 0, n).to(device));
    torch::Tensor mu = mu_d.to(torch::kCPU).contiguous();
    std::copy(mu.data_ptr<float>(), mu.data_ptr<float>() + n * enc.latents,
              enc.mu.begin() + static_cast<long>(begin) * enc.latents);
    torch::Tensor kl = kl_per_latent(mu_d, logvar).to(torch::kCPU, torch::kFloat64).contiguous();
    for (int64_t i = 0; i < n; ++i) {
      std::vector<double>& sum = enc.kl_sum[static_cast<size_t>(frames[begin + i].first)];
      const double* row = kl.data_ptr<double>() + i * enc.latents;
      for (int k = 0; k < enc.latents; ++k) sum[static_cast<size_t>(k)] += row[k];
    }
    if (progress) progress->advance(n);
  }
  if (progress) progress->finish();
  return enc;
}

// Every frame of every episode, in order (at(e, t) addresses them).
Encoded encode_all(BetaVae& vae, const EpisodeSet& eps, const GreyView& view,
                   const torch::Device& device, bool quiet) {
  std::vector<std::pair<int, int>> frames;
  std::vector<long> offset;
  for (int e = 0; e < static_cast<int>(eps.episodes.size()); ++e) {
    offset.push_back(static_cast<long>(frames.size()));
    for (int t = 0; t < eps.episodes[e].frames; ++t) frames.emplace_back(e, t);
  }
  Encoded enc = encode_frames(vae, eps, view, frames, device, quiet);
  enc.offset = std::move(offset);
  return enc;
}

// Each latent's mean KL over the encoded frames of the episodes, but those of `skip` (sorted).
std::vector<double> mean_kl(const Encoded& enc, const std::vector<int>& skip = {}) {
  std::vector<double> kl(static_cast<size_t>(enc.latents), 0.0);
  long frames = 0;
  for (int e = 0; e < static_cast<int>(enc.kl_sum.size()); ++e) {
    if (std::binary_search(skip.begin(), skip.end(), e)) continue;
    frames += enc.encoded[static_cast<size_t>(e)];
    for (size_t k = 0; k < kl.size(); ++k) kl[k] += enc.kl_sum[e][k];
  }
  for (double& v : kl) v /= static_cast<double>(std::max(frames, 1L));
  return kl;
}

// ---- stage vae ----------------------------------------------------------------------------

// The VAE's loss over a set of frames (no validation: it is judged by its traversals and by
// the causes it yields).
class VaeObjective : public Objective {
 public:
  VaeObjective(const EpisodeSet& eps, const GreyView& view,
               const std::vector<std::pair<int, int>>& frames, BetaVae& vae,
               const torch::Device& device, const VaeSettings& v)
      : eps_(eps), view_(view), frames_(frames), vae_(vae), device_(device), beta_(v.beta),
        batch_(torch::empty({v.batch_size, 1, kVaeSize, kVaeSize})) {}

  void set_training(bool on) override { on ? vae_->train() : vae_->eval(); }

  BatchLoss loss(bool, const uint32_t* rows, int64_t n) override {
    fill_views(eps_, view_, frames_.data(), rows, n, batch_.data_ptr<float>());
    torch::Tensor x = batch_.narrow(0, 0, n).to(device_);
    VaeOutput o = vae_->forward(x, true);
    VaeLoss l = vae_loss(o.logits, x, o.mu, o.logvar, beta_);
    return {l.loss, {l.recon, l.kl}};
  }

 private:
  const EpisodeSet& eps_;
  const GreyView& view_;
  const std::vector<std::pair<int, int>>& frames_;
  BetaVae& vae_;
  torch::Device device_;
  double beta_;
  torch::Tensor batch_;
};

json train_vae(const Settings& s, const EpisodeSet& eps, const GreyView& view,
               const ComputeDevice& dev, const std::string& out, bool quiet) {
  const torch::Device& device = dev.device;
  const auto start = Clock::now();
  std::vector<std::pair<int, int>> frames;
  for (int e = 0; e < static_cast<int>(eps.episodes.size()); ++e)
    for (int t = 0; t < eps.episodes[e].frames; ++t) frames.emplace_back(e, t);
  const long total = static_cast<long>(frames.size());
  if (total == 0) throw DataError("data folder '" + eps.dir + "' holds no frame");
  if (s.vae.max_frames > 0 && s.vae.max_frames < total) {
    // A seeded subset, back in data order (locality while filling batches).
    Rng rng(derive_seed(s.train.seed, kVaeSubsetStream));
    frames = subset_in_order(frames, static_cast<size_t>(s.vae.max_frames), rng, SubsetDraw::Partial);
  }
  const size_t n_frames = frames.size();

  torch::manual_seed(s.train.seed);
  BetaVae vae(s.vae.latents);
  vae->to(device);
  torch::optim::Adam opt(vae->parameters(), torch::optim::AdamOptions(s.vae.lr));
  std::optional<Progress> progress;
  if (!quiet) progress.emplace("train vae", static_cast<long>(n_frames) * s.vae.epochs);
  LoopPlan plan;
  plan.last_epoch = s.vae.epochs;
  plan.batch_size = s.vae.batch_size;
  plan.train_size = n_frames;
  plan.shuffle_seed = s.train.seed ^ kVaeOrderStream;
  plan.torch_seed = s.train.seed ^ kVaeNoiseStream;  // the reparameterisation noise
  plan.device = &dev;
  plan.progress = progress ? &*progress : nullptr;
  plan.stop_patience = s.vae.patience;
  plan.stop_min_improvement = s.vae.min_improvement;
  const int epochs = s.vae.epochs;
  plan.note = [epochs](int epoch, double v) { return epoch_note(epoch, epochs, "loss", v, 2); };
  LoopState state;
  state.lr = s.vae.lr;
  std::string metrics;
  // The weights of the epoch with the lowest loss are the ones kept: a late spike of the loss
  // (one seen: 55 -> 732 in the epoch that ended a run) must not replace a trained VAE.
  json kept;
  std::string kept_bytes;
  VaeObjective objective(eps, view, frames, vae, device, s.vae);
  const LoopTotals totals = train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    const json line = {{"epoch", r.epoch},
                       {"recon", r.train_parts[0]},
                       {"kl", r.train_parts[1]},
                       {"loss", r.train_loss},
                       {"seconds", r.train_seconds},
                       {"images_per_s", r.samples_per_s}};
    metrics += line.dump() + "\n";
    if (r.improved) {
      kept = line;
      kept_bytes = save_module_bytes(*vae);
    }
  });
  if (progress) progress->finish();
  if (state.best_epoch != totals.last_epoch)
    load_module_bytes(*vae, kept_bytes, device, "the VAE of epoch " + std::to_string(state.best_epoch));
  write_file_atomic(out + "/" + kCimVaeFile, kept_bytes);
  write_file_atomic(out + "/" + kCimVaeMetrics, metrics);
  // Over the frames it trained on.
  const std::vector<double> kl = mean_kl(encode_frames(vae, eps, view, frames, device, true));
  const int active = active_latents(kl);
  json fig = kept;  // recon, kl, loss of the kept epoch
  fig["frames"] = static_cast<long>(n_frames);
  fig["epochs"] = totals.last_epoch;
  fig["kept_epoch"] = state.best_epoch;
  fig["max_epochs"] = s.vae.epochs;
  fig["stopped_early"] = totals.stopped_early;
  fig["beta"] = s.vae.beta;
  fig["kl_per_latent"] = kl;
  fig["active_latents"] = active;
  fig["active_kl_threshold"] = kActiveKlNats;
  fig["seconds"] = seconds_since(start);
  fig["train_seconds"] = totals.seconds;
  say(quiet, "  vae: " + std::to_string(totals.last_epoch) + " epochs" +
                 (totals.stopped_early ? " (the loss stopped falling)" : "") +
                 (state.best_epoch != totals.last_epoch
                      ? ", kept epoch " + std::to_string(state.best_epoch) + " (lowest loss)"
                      : "") +
                 " on " + std::to_string(n_frames) + " frames, recon " +
                 fmt("%.2f", kept["recon"].get<double>()) + " kl " +
                 fmt("%.2f", kept["kl"].get<double>()) + " (beta " + fmt("%g", s.vae.beta) +
                 ") per image, " + std::to_string(active) + " of " + std::to_string(s.vae.latents) +
                 " latents active (KL > " + fmt("%g", kActiveKlNats) + " nats), " +
                 fmt("%.0f", totals.samples_per_s()) + " images/s, " +
                 format_duration(seconds_since(start)));
  return fig;
}

// ---- stages series and causes ---------------------------------------------------------------

struct SeriesRows {
  std::vector<std::pair<int, int>> rows;  // (episode, t)
  std::vector<std::vector<double>> speed;                  // per episode
  std::vector<std::vector<std::vector<double>>> latents;   // [latent][episode][row]
  std::string csv;                                         // series.csv
};

// The series as series.csv holds them, and the tests run on exactly the numbers a reader of
// that file gets: each value is printed with %.9g (enough to tell floats apart) and parsed
// back, so `causaldrive granger --input RUN` reproduces causes.json to the last bit.
// Only the predictor's training episodes give rows (the tests never see its validation
// episodes), every stride-th frame; a row whose speed moved under injected noise since the
// previous row is left out and ends a segment, so no lag spans the noise. The "episode" column
// numbers these segments.
SeriesRows build_series(const EpisodeSet& eps, const Encoded& enc, int stride,
                        const std::vector<int>& val_episodes) {
  SeriesRows s;
  const int n = static_cast<int>(eps.episodes.size());
  s.latents.assign(enc.latents, {});
  s.csv = "episode,speed";
  for (int i = 0; i < enc.latents; ++i) s.csv += ",z" + std::to_string(i);
  s.csv += "\n";
  char buf[40];
  auto cell = [&](float v) {
    std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));
    s.csv += ',';
    s.csv += buf;
    return std::strtod(buf, nullptr);
  };
  bool open = false;  // whether the last segment takes more rows
  for (int e = 0; e < n; ++e) {
    if (std::binary_search(val_episodes.begin(), val_episodes.end(), e)) continue;
    open = false;
    const PackedEpisode& ep = eps.episodes[e];
    for (int t = 0; t < ep.frames; t += stride) {
      if (t > 0 && !expert_motion(ep, t - stride, t)) {
        open = false;
        continue;
      }
      if (!open) {
        s.speed.emplace_back();
        for (auto& z : s.latents) z.emplace_back();
        open = true;
      }
      const int segment = static_cast<int>(s.speed.size()) - 1;
      s.rows.emplace_back(e, t);
      s.csv += std::to_string(segment);
      s.speed[segment].push_back(cell(ep.speed[t]));
      const float* mu = enc.at(e, t);
      for (int i = 0; i < enc.latents; ++i) s.latents[i][segment].push_back(cell(mu[i]));
      s.csv += '\n';
    }
  }
  return s;
}

json causes_json(const std::string& method, const CimSettings& cim, const CauseSelection& sel,
                 const SeriesRows& s, const EpisodeSet& eps, const std::vector<double>& kl,
                 const std::vector<bool>& eligible) {
  json j;
  std::vector<int> active;
  for (size_t k = 0; k < kl.size(); ++k)
    if (is_active_latent(kl[k])) active.push_back(static_cast<int>(k));
  j["target"] = "speed";
  j["method"] = method;
  j["selection"] = sel.rule;
  j["min_partial_r2"] = cim.min_partial_r2;
  j["lags"] = cim.lags;
  j["alpha"] = cim.alpha;
  j["correction"] = cim.correction;
  j["max_causes"] = cim.max_causes;
  j["series_stride"] = cim.series_stride;
  j["candidates"] = cim.candidates;
  j["active_latents"] = active;  // mean KL > 0.01 nats on the predictor's training episodes
  j["rows"] = sel.rows;
  j["series_rows"] = static_cast<long>(s.rows.size());
  j["threshold_p"] = sel.threshold_p;
  j["significant_count"] = sel.significant;
  j["capped"] = sel.capped;
  j["fallback"] = sel.fallback;
  j["ranked"] = sel.ranked;
  j["selected"] = sel.selected;
  json lat = json::array();
  for (const LatentTest& t : sel.tests)
    lat.push_back({{"index", t.index},
                   {"f_stat", json_number(t.test.f_stat)},
                   {"p_value", t.test.p_value},
                   {"p_adjusted", t.p_adjusted},
                   {"df_num", t.test.df_num},
                   {"df_den", t.test.df_den},
                   {"partial_r2", json_number(t.test.partial_r2)},
                   {"kl", kl[static_cast<size_t>(t.index)]},
                   {"significant", t.significant},
                   {"selected", t.selected}});
  j["latents"] = lat;

  // What the picked latents track: Pearson r with the recorded causes on the series rows.
  std::map<std::string, std::vector<double>> truth;
  for (const auto& name : ground_truth_names())
    for (const auto& [e, t] : s.rows) truth[name].push_back(ground_truth_value(eps.episodes[e], name, t));
  auto latent_series = [&](int i) {
    std::vector<double> v;
    for (const auto& per_ep : s.latents[i]) v.insert(v.end(), per_ep.begin(), per_ep.end());
    return v;
  };
  json gt;
  gt["rows"] = static_cast<long>(s.rows.size());
  gt["note"] = "Pearson r of each Granger-picked latent (ranked) with the recorded causes";
  json per = json::array();
  std::map<std::string, std::pair<int, double>> best;
  std::vector<json> corr(s.latents.size());
  for (int i = 0; i < static_cast<int>(s.latents.size()); ++i) {
    const std::vector<double> z = latent_series(i);
    const bool ranked = std::find(sel.ranked.begin(), sel.ranked.end(), i) != sel.ranked.end();
    json r;
    for (const auto& name : ground_truth_names()) {
      const double c = pearson(z, truth[name]);
      r[name] = json_number(c);
      if (std::isfinite(c) && (!best.count(name) || std::fabs(c) > std::fabs(best[name].second)))
        best[name] = {i, c};
    }
    corr[i] = r;
    if (ranked) per.push_back({{"index", i}, {"correlation", r}});
  }
  gt["latents"] = per;
  json b = json::object();
  for (const auto& [name, v] : best) b[name] = {{"index", v.first}, {"r", v.second}};
  gt["best_latent_per_cause"] = b;
  j["ground_truth"] = gt;

  // The three rules side by side on the same series (issue: a selection that tests
  // something): how many latents pass each, which it picks and what those track.
  json rules = json::object();
  for (const char* rule : {"bivariate", "conditional", "partial_r2"}) {
    CimSettings c = cim;
    c.selection = rule;
    const CauseSelection other =
        rule == sel.rule ? sel : select_causes(s.speed, s.latents, c, false, eligible);
    json picked = json::array();
    for (int i : other.ranked) {
      std::string cause;
      double top = 0;
      for (const auto& [name, v] : corr[i].items())
        if (v.is_number() && std::fabs(v.get<double>()) > std::fabs(top)) {
          top = v.get<double>();
          cause = name;
        }
      picked.push_back({{"index", i},
                        {"strongest_cause", cause},
                        {"r", top},
                        {"active", is_active_latent(kl[static_cast<size_t>(i)])}});
    }
    rules[rule] = {{"passing", other.significant},
                   {"fallback", other.fallback},
                   {"capped", other.capped},
                   {"picked", picked}};
  }
  j["rules"] = rules;
  return j;
}

// ---- stage predictor -----------------------------------------------------------------------

// The speed predictor's loss: the selected latents' last cim.history means -> speed[t+1].
class PredictorObjective : public Objective {
 public:
  PredictorObjective(const EpisodeSet& eps, const Encoded& enc, const std::vector<int>& selected,
                     const std::vector<SampleRef>& train, const std::vector<SampleRef>& val,
                     SpeedPredictor& net, const torch::Device& device, const Settings& s)
      : eps_(eps), enc_(enc), selected_(selected), train_(train), val_(val), net_(net),
        device_(device), loss_kind_(s.train.loss), H_(s.cim.history), hs_(s.cim.history_stride) {
    const int V = static_cast<int>(selected.size());
    x_ = torch::empty({s.cim.batch_size, V, H_});
    y_ = torch::empty({s.cim.batch_size, 1});
  }

  void set_training(bool on) override { on ? net_->train() : net_->eval(); }

  BatchLoss loss(bool training, const uint32_t* rows, int64_t n) override {
    const std::vector<SampleRef>& list = training ? train_ : val_;
    const int V = static_cast<int>(selected_.size());
    float* x = x_.data_ptr<float>();
    float* y = y_.data_ptr<float>();
    for (int64_t i = 0; i < n; ++i) {
      const SampleRef& p = list[rows[i]];
      for (int k = 0; k < H_; ++k) {
        const float* mu = enc_.at(p.episode, p.t - (H_ - 1 - k) * hs_);  // oldest first
        for (int v = 0; v < V; ++v) x[(i * V + v) * H_ + k] = mu[selected_[v]];
      }
      y[i] = eps_.episodes[p.episode].speed[p.t + 1];
    }
    torch::Tensor pred = net_->forward(x_.narrow(0, 0, n).to(device_));
    torch::Tensor target = y_.narrow(0, 0, n).to(device_);
    return {loss_kind_ == "l2" ? torch::mse_loss(pred, target) : torch::l1_loss(pred, target), {}};
  }

 private:
  const EpisodeSet& eps_;
  const Encoded& enc_;
  const std::vector<int>& selected_;
  const std::vector<SampleRef>& train_;
  const std::vector<SampleRef>& val_;
  SpeedPredictor& net_;
  torch::Device device_;
  std::string loss_kind_;
  int H_, hs_;
  torch::Tensor x_, y_;
};

// Trains the predictor into out/predictor.pt; returns the stage's figures for run.json.
json train_predictor(const Settings& s, const std::string& method, const EpisodeSet& eps,
                                const Encoded& enc, const std::vector<int>& selected,
                                const std::string& init_predictor, const ComputeDevice& dev,
                                const std::string& out, bool quiet) {
  const torch::Device& device = dev.device;
  const auto start = Clock::now();
  const int H = s.cim.history, hs = s.cim.history_stride;
  const int n_eps = static_cast<int>(eps.episodes.size());
  // A few-shot run: its train.max_samples labels are all it sees, so no episode is held out.
  const bool fewshot = !init_predictor.empty();
  const std::vector<int> val_eps =
      fewshot ? std::vector<int>{} : choose_val_episodes(n_eps, s.train.val_fraction, s.train.seed);
  std::vector<SampleRef> train, val;
  for (int e = 0; e < n_eps; ++e) {
    const bool is_val = std::binary_search(val_eps.begin(), val_eps.end(), e);
    for (int t = (H - 1) * hs; t + 1 < eps.episodes[e].frames; ++t)
      if (expert_motion(eps.episodes[e], t, t + 1))  // speed[t+1] is the expert's, not noise
        (is_val ? val : train).push_back({e, t});
  }
  if (train.empty())
    throw DataError("data folder '" + eps.dir + "' gives no training sample for the speed "
                    "predictor (episodes shorter than " + std::to_string((H - 1) * hs + 2) +
                    " frames)");
  // train.max_samples caps the training samples only (seeded subset, data order kept);
  // validation always uses every sample of the held-out episodes.
  if (s.train.max_samples > 0) {
    Rng rng(derive_seed(s.train.seed, kPredSubsetStream));
    train = subset_in_order(train, static_cast<size_t>(s.train.max_samples), rng, SubsetDraw::Partial);
  }

  const int V = static_cast<int>(selected.size());
  SpeedPredictorOptions po;
  po.variables = V;
  po.history = H;
  po.units = method == "cim-mlp" ? s.cim.mlp_encoder_units : s.cim.encoder_units;
  po.hidden = s.cim.hidden;
  torch::manual_seed(s.train.seed);
  SpeedPredictor net(po);
  if (!init_predictor.empty()) load_module_bytes(*net, init_predictor, torch::kCPU, "--init predictor");
  net->to(device);
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(s.cim.lr));
  PredictorObjective objective(eps, enc, selected, train, val, net, device, s);

  std::string metrics;
  LoopState state;
  state.lr = s.cim.lr;
  std::string best_bytes;
  // Few-shot: cim.fewshot_steps Adam steps over the labels (batches of at most all of them),
  // keeping the last weights; otherwise cim.epochs, keeping the best validation epoch.
  const int batch = fewshot ? static_cast<int>(std::min<size_t>(s.cim.batch_size, train.size()))
                            : s.cim.batch_size;
  const long steps_per_epoch = (static_cast<long>(train.size()) + batch - 1) / batch;
  const int epochs = fewshot ? static_cast<int>((s.cim.fewshot_steps + steps_per_epoch - 1) /
                                                steps_per_epoch)
                             : s.cim.epochs;
  if (fewshot) {
    // Epoch 0: the initial predictor's loss on the few-shot labels (eval mode), for comparison.
    PredictorObjective on_labels(eps, enc, selected, train, train, net, device, s);
    metrics += json({{"epoch", 0}, {"train_loss", validation_loss(on_labels, train.size(), batch, &dev)}})
                   .dump() + "\n";
  }
  std::optional<Progress> progress;
  if (!quiet) progress.emplace("train " + method + " predictor", static_cast<long>(train.size()) * epochs);
  LoopPlan plan;
  plan.last_epoch = epochs;
  plan.batch_size = batch;
  plan.train_size = train.size();
  plan.val_size = val.size();
  plan.shuffle_seed = s.train.seed ^ kPredOrderStream;
  plan.device = &dev;
  plan.progress = progress ? &*progress : nullptr;
  plan.note = [epochs](int epoch, double v) { return epoch_note(epoch, epochs, "loss", v, 4); };
  double last_selection = 0;  // the kept weights' loss when they are the last (few-shot)
  const LoopTotals totals = train_epochs(objective, opt, plan, state, [&](const EpochResult& r) {
    last_selection = r.selection();
    json m = {{"epoch", r.epoch}, {"train_loss", r.train_loss}};
    if (r.val_loss) m["val_loss"] = *r.val_loss;
    m["seconds"] = r.seconds_since_start();
    m["samples_per_s"] = r.samples_per_s;
    metrics += m.dump() + "\n";
    if (r.improved || fewshot) best_bytes = save_module_bytes(*net);
  });
  if (progress) progress->finish();
  write_file_atomic(out + "/" + kCimPredictorFile, best_bytes);
  write_file_atomic(out + "/" + kCimPredictorMetrics, metrics);

  const int val_episodes = static_cast<int>(val_eps.size());
  return {{"variables", V},
          {"epochs", epochs},
          {"fewshot", fewshot},
          {"steps", steps_per_epoch * epochs},
          {"labels", static_cast<long>(train.size() + val.size())},
          {"kept_epoch", fewshot ? epochs : state.best_epoch},
          {"kept_loss", fewshot ? last_selection : state.best_loss},
          {"best_epoch", state.best_epoch},
          {"best_loss", state.best_loss},
          {"loss", s.train.loss},
          {"has_validation", !val.empty()},
          {"train_samples", static_cast<long>(train.size())},
          {"val_samples", static_cast<long>(val.size())},
          {"train_episodes", n_eps - val_episodes},
          {"val_episodes", val_episodes},
          {"samples_per_s", totals.samples_per_s()},
          {"seconds", seconds_since(start)}};
}

// The traversal's base frame: the first frame with a leader within 20 m, else the first with
// anything in the view, else the very first frame.
std::vector<float> base_view(const EpisodeSet& eps, const GreyView& view, json& where) {
  std::vector<float> v(kVaeSize * kVaeSize);
  auto take = [&](int e, int t, const char* why) {
    view_from_packed(view, eps.episodes[e].frame_data.data() + static_cast<size_t>(t) * eps.frame_pixels(),
                     v.data());
    where = {{"episode", e}, {"t", t}, {"file", eps.episodes[e].file}, {"why", why}};
    return v;
  };
  for (int e = 0; e < static_cast<int>(eps.episodes.size()); ++e)
    for (int t = 0; t < eps.episodes[e].frames; ++t) {
      const double present = ground_truth_value(eps.episodes[e], "lead_present", t);
      const double d = ground_truth_value(eps.episodes[e], "lead_distance", t);
      if (present == 1.0 && d < 20) return take(e, t, "leader within 20 m");
    }
  for (int e = 0; e < static_cast<int>(eps.episodes.size()); ++e)
    for (int t = 0; t < eps.episodes[e].frames; ++t) {
      const uint8_t* p = eps.episodes[e].frame_data.data() + static_cast<size_t>(t) * eps.frame_pixels();
      for (size_t i = 0; i < eps.frame_pixels(); ++i)
        if (p[i] & view.mask) return take(e, t, "first frame with something in the view");
    }
  return take(0, 0, "first frame");
}

// run.json as the stages go: each stage's files are written first, then commit() names the
// stage as done (atomically), so a rerun skips finished stages and redoes an interrupted one.
struct StagedRecord {
  std::string out;
  json record;

  bool done(const std::string& stage) const {
    for (const auto& st : record.at("stages"))
      if (st == stage) return true;
    return false;
  }
  void commit(const std::string& stage, const json& figures) {
    record["figures"][stage] = figures;
    if (!done(stage)) record["stages"].push_back(stage);
    write_file_atomic(out + "/" + kCimRunJson, record.dump(2) + "\n");
  }
};

// Stages series and causes: the latent series, the Granger tests and the selection.
void causes_stage(const Settings& s, const std::string& method, const EpisodeSet& eps,
                  const Encoded& enc, StagedRecord& run, bool quiet) {
  const auto start = Clock::now();
  std::vector<int> val =
      choose_val_episodes(static_cast<int>(eps.episodes.size()), s.train.val_fraction, s.train.seed);
  std::sort(val.begin(), val.end());
  const SeriesRows rows = build_series(eps, enc, s.cim.series_stride, val);
  // Which latents are active, on the predictor's training episodes only.
  const std::vector<double> kl = mean_kl(enc, val);
  std::vector<bool> active(kl.size());
  for (size_t k = 0; k < kl.size(); ++k) active[k] = is_active_latent(kl[k]);
  const std::vector<bool> eligible = s.cim.candidates == "active" ? active : std::vector<bool>{};
  if (!run.done("series")) {
    write_file_atomic(run.out + "/" + kCimSeriesCsv, rows.csv);
    run.commit("series", {{"rows", static_cast<long>(rows.rows.size())}, {"stride", s.cim.series_stride}});
  }
  const CauseSelection sel =
      select_causes(rows.speed, rows.latents, s.cim, method == "cim-mlp", eligible);
  const json c = causes_json(method, s.cim, sel, rows, eps, kl, eligible);
  write_file_atomic(run.out + "/" + kCimCausesJson, c.dump(2) + "\n");
  const bool by_share = sel.rule == "partial_r2";
  const std::string rule =
      by_share ? "partial R2 >= " + fmt("%g", s.cim.min_partial_r2)
               : sel.rule + " test, " + s.cim.correction + " alpha " + fmt("%g", s.cim.alpha);
  std::string list;
  for (int i : sel.ranked)
    list += " z" + std::to_string(i) +
            (by_share ? " (partial R2 " + fmt("%.3g", sel.tests[i].test.partial_r2) + ")"
                      : " (p " + fmt("%.3g", sel.tests[i].test.p_value) + ")");
  if (sel.fallback)
    std::fprintf(stderr, "warning: no latent Granger-causes the speed by the %s rule; the speed "
                         "predictor uses the best-ranked latent z%d alone\n",
                 rule.c_str(), sel.ranked[0]);
  const long n_active = std::count(active.begin(), active.end(), true);
  say(quiet, "  causes: " + std::to_string(sel.significant) + " of " +
                 (s.cim.candidates == "active"
                      ? std::to_string(n_active) + " active (of " + std::to_string(s.vae.latents) + ")"
                      : std::to_string(s.vae.latents)) +
                 " latents pass (" + rule + ", " +
                 std::to_string(s.cim.lags) + " lags, " + std::to_string(sel.rows) +
                 " rows); picked" + list +
                 (method == "cim-mlp" ? "; cim-mlp uses all latents" : ""));
  run.commit("causes", {{"significant", sel.significant},
                        {"candidates", s.cim.candidates},
                        {"active_latents", n_active},
                        {"ranked", sel.ranked},
                        {"selected_count", static_cast<int>(sel.selected.size())},
                        {"fallback", sel.fallback},
                        {"capped", sel.capped},
                        {"seconds", seconds_since(start)}});
}

// Stage pictures: the traversal of the picked latents and the Granger p-value chart.
void pictures_stage(const EpisodeSet& eps, const GreyView& view, BetaVae& vae, const json& causes,
                    StagedRecord& run) {
  json where;
  const std::vector<float> base = base_view(eps, view, where);
  std::vector<int> ranked = causes.at("ranked").get<std::vector<int>>();
  write_traversal_png(run.out + "/" + kCimTraversalPng, vae, base, ranked);
  std::vector<double> p;
  std::vector<bool> sel_flags, sig_flags;
  for (const auto& l : causes.at("latents")) {
    p.push_back(l.at("p_value").get<double>());
    // Highlight the Granger picks (for cim-mlp every latent is an input; the picks still matter).
    const int i = l.at("index").get<int>();
    sel_flags.push_back(std::find(ranked.begin(), ranked.end(), i) != ranked.end());
    sig_flags.push_back(l.at("significant").get<bool>());
  }
  write_granger_png(run.out + "/" + kCimGrangerPng, p, sel_flags, sig_flags,
                    causes.at("threshold_p").get<double>());
  run.commit("pictures", {{"traversal", kCimTraversalPng},
                          {"granger", kCimGrangerPng},
                          {"traversal_rows", ranked},
                          {"base_frame", where}});
}

// The run.json of a new run.
json new_record(const std::string& method, const json& settings, const std::string& data_dir,
                const std::string& init_dir, const std::string& vae_dir,
                const std::string& device, const EpisodeSet& eps, const GreyView& view) {
  return {{"version", kCimRunVersion},
          {"method", method},
          {"settings", settings},
          {"data_dir", data_dir},
          {"init", init_dir},
          {"vae_from", vae_dir},
          {"device", device},
          {"input",
           {{"format", "bev"},
            {"channels", eps.channels},
            {"height", eps.height},
            {"width", eps.width},
            {"channel_names", eps.channel_names},
            {"dt", eps.dt},
            {"metres_per_pixel", eps.metres_per_pixel},
            {"view_channels", view.channels},
            {"episodes", static_cast<int>(eps.episodes.size())},
            {"frames", eps.total_frames()}}},
          {"stages", json::array()},
          {"figures", json::object()}};
}

}  // namespace

TrainSummary train_cim(const Settings& settings_in, const TrainRequest& req) {
  const auto run_start = Clock::now();
  const Settings s = effective_settings(req.method, settings_in);
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  if (!req.init.empty() && !req.vae_from.empty())
    throw ConfigError("give --init or --vae, not both (--init already brings its run's VAE)");
  const std::string out = req.out_dir;
  const std::string data_dir = canonical_dir(req.data_dir);
  const std::string init_dir = canonical_dir(req.init), vae_dir = canonical_dir(req.vae_from);
  const json settings_json = settings_to_json(s);

  // Refusals first, before any data is read.
  refuse_other_method_folder(out, req.method);
  std::optional<CimRunInfo> previous = read_cim_run(out);
  auto inputs = [](const std::string& data, const std::string& init, const std::string& vae) {
    return "data " + data + (init.empty() ? "" : ", --init " + init) +
           (vae.empty() ? "" : ", --vae " + vae);
  };
  if (previous)
    refuse_other_run({previous->method, previous->record.at("settings"),
                      inputs(previous->data_dir, previous->init, previous->vae_from)},
                     {req.method, settings_json, inputs(data_dir, init_dir, vae_dir)}, out,
                     {"vae", "cim", "bev", "train"}, may_differ);
  std::optional<CimRunInfo> init_run, vae_run;
  if (!init_dir.empty()) {
    init_run = require_cim_run(init_dir, req.method, {"vae", "causes", "predictor"}, "--init");
    check_same_vae(*init_run, s.vae, req.method, "--init");
    const CimSettings& a = init_run->cim;
    if (a.history != s.cim.history || a.history_stride != s.cim.history_stride ||
        a.encoder_units != s.cim.encoder_units || a.mlp_encoder_units != s.cim.mlp_encoder_units ||
        a.hidden != s.cim.hidden)
      throw ConfigError("--init " + init_dir + ": its speed predictor has another shape (cim.history, "
                        "history_stride, encoder_units, mlp_encoder_units or hidden differ)");
  }
  if (!vae_dir.empty()) {
    vae_run = require_cim_run(vae_dir, "", {"vae"}, "--vae");
    check_same_vae(*vae_run, s.vae, req.method, "--vae");
  }

  const ComputeDevice dev = training_device(s.train);
  const torch::Device& device = dev.device;
  const std::string& device_name = dev.name;

  const EpisodeSet eps = load_episode_set(req.data_dir);
  if (eps.layout != FrameLayout::BitPlanes)
    throw ConfigError(req.method + " trains on BEV data (its VAE sees a grey view of the BEV's "
                      "layers); " + req.data_dir + " holds RGB frames (sense.view = \"camera\")");
  const GreyView view = resolve_view(s.vae.view, eps.channel_names, eps.height, eps.width);
  const CimRunInfo* source = init_run ? &*init_run : vae_run ? &*vae_run : nullptr;
  if (source) check_same_input(*source, eps, init_run ? "--init" : "--vae");

  StagedRecord run{out, json()};
  if (previous) {
    run.record = previous->record;
    const json& in = run.record.at("input");
    if (in.at("frames").get<long>() != eps.total_frames() ||
        in.at("episodes").get<int>() != static_cast<int>(eps.episodes.size()))
      throw ConfigError(out + " holds a run trained on other data (" +
                        std::to_string(in.at("episodes").get<int>()) +
                        " episodes), but " + data_dir + " now gives " +
                        std::to_string(eps.episodes.size()) + ": the data changed; train into "
                        "another --out folder");
  } else {
    run.record = new_record(req.method, settings_json, data_dir, init_dir, vae_dir, device_name,
                            eps, view);
    run.record["runtime"] = dev.record();
  }
  fs::create_directories(out);
  remove_stale_temporaries(out);
  if (!previous) write_file_atomic(out + "/" + kCimRunJson, run.record.dump(2) + "\n");
  say(req.quiet, "cim pipeline (" + req.method + ") -> " + out);

  // Stage vae: trained here, or copied from --init / --vae.
  if (!run.done("vae")) {
    if (source) {
      write_file_atomic(out + "/" + kCimVaeFile, read_file_bytes(source->dir + "/" + kCimVaeFile));
      if (fs::exists(source->dir + "/" + kCimVaeMetrics))
        write_file_atomic(out + "/" + kCimVaeMetrics, read_file_bytes(source->dir + "/" + kCimVaeMetrics));
      say(req.quiet, "  vae: copied from " + source->dir);
      run.commit("vae", {{"copied_from", source->dir}});
    } else {
      run.commit("vae", train_vae(s, eps, view, dev, out, req.quiet));
    }
  }
  BetaVae vae(s.vae.latents);
  load_module_bytes(*vae, read_file_bytes(out + "/" + kCimVaeFile), device, out + "/" + kCimVaeFile);
  vae->eval();

  std::optional<Encoded> enc;
  auto encoded = [&]() -> const Encoded& {
    if (!enc) enc = encode_all(vae, eps, view, device, req.quiet);
    return *enc;
  };

  // Stages series and causes (a few-shot run keeps its init run's causes).
  if (init_run) {
    if (!run.done("causes")) {
      json c = json::parse(read_file_bytes(init_run->dir + "/" + kCimCausesJson));
      c["copied_from"] = init_run->dir;
      write_file_atomic(out + "/" + kCimCausesJson, c.dump(2) + "\n");
      run.commit("causes", {{"copied_from", init_run->dir}, {"selected", c.at("selected")}});
    }
  } else if (!run.done("series") || !run.done("causes")) {
    causes_stage(s, req.method, eps, encoded(), run, req.quiet);
  }
  const json causes = json::parse(read_file_bytes(out + "/" + kCimCausesJson));
  const std::vector<int> selected = causes.at("selected").get<std::vector<int>>();

  double samples_per_s = 0;
  const bool predictor_done_before = run.done("predictor");
  if (!predictor_done_before) {
    const std::string init_bytes =
        init_run ? read_file_bytes(init_run->dir + "/" + kCimPredictorFile) : std::string();
    json figures = train_predictor(s, req.method, eps, encoded(), selected, init_bytes, dev,
                                   out, req.quiet);
    samples_per_s = figures.at("samples_per_s").get<double>();
    if (init_run) figures["init"] = init_run->dir;
    run.commit("predictor", figures);
  }
  const json& pf = run.record["figures"]["predictor"];
  TrainSummary sum = train_summary(req, device_name, pf.at("train_samples").get<long>(),
                                   pf.at("val_samples").get<long>(),
                                   pf.at("train_episodes").get<int>(),
                                   pf.at("val_episodes").get<int>());
  sum.weights_file = kCimPredictorFile;
  sum.samples_per_s = samples_per_s;
  if (predictor_done_before) sum.resumed_from = s.cim.epochs;
  sum.epochs_done = pf.at("epochs").get<int>();
  // The weights kept: the best validation epoch, or a few-shot run's last one.
  const bool last_kept = pf.value("fewshot", false);
  sum.last_kept = last_kept;
  sum.best_epoch = pf.value("kept_epoch", pf.at("best_epoch").get<int>());
  sum.best_loss = pf.value("kept_loss", pf.at("best_loss").get<double>());
  say(req.quiet, "  predictor: " + std::to_string(selected.size()) + " input variable(s), " +
                     (last_kept ? "kept the last epoch " : "best epoch ") +
                     std::to_string(sum.best_epoch) + ", " + (sum.has_validation ? "validation" : "training") +
                     " " + s.train.loss + " loss " + fmt("%.4f", sum.best_loss) + " m/s -> " + out +
                     "/" + kCimPredictorFile);

  if (!run.done("pictures")) pictures_stage(eps, view, vae, causes, run);
  sum.seconds = seconds_since(run_start);
  return sum;
}

// ---- the agent ------------------------------------------------------------------------------

namespace {

// The history frames' grey views -> the VAE's mu -> the selected latents (all of them for
// cim-mlp) -> the speed predictor -> target speed (>= 0) -> SpeedPid (seed 000 eq. 2). A
// free-steering ego steers along the route (the expert's path tracker) or, with eval.cim_path,
// along the path a dim/rip model plans (its agent runs beside; only its steer is used).
class CimAgent : public Agent {
 public:
  CimAgent(const std::string& method, const std::string& dir, const Settings& s, const World* world)
      : method_(method),
        free_(s.ego.lateral == "free"),
        world_(world),
        run_(require_cim_run(dir, method, {"vae", "causes", "predictor"}, "agent '" + method + "':")),
        vae_(run_.vae.latents),
        pid_(s.control, EgoModel(s.ego), s.world.dt) {
    view_ = resolve_view(run_.vae.view, run_.channel_names, run_.height, run_.width);
    try {
      const nlohmann::json causes = nlohmann::json::parse(read_file_bytes(dir + "/" + kCimCausesJson));
      selected_ = causes.at("selected").get<std::vector<int>>();
    } catch (const nlohmann::json::exception& e) {
      throw DataError(dir + "/" + kCimCausesJson + " is damaged (" + e.what() + ")");
    }
    if (selected_.empty()) throw DataError(dir + "/" + kCimCausesJson + " selects no latent");
    for (int i : selected_)
      if (i < 0 || i >= run_.vae.latents)
        throw DataError(dir + "/" + kCimCausesJson + " selects latent " + std::to_string(i) +
                        " of " + std::to_string(run_.vae.latents));
    load_module_bytes(*vae_, read_file_bytes(dir + "/" + kCimVaeFile), torch::kCPU,
                      dir + "/" + kCimVaeFile);
    vae_->eval();
    SpeedPredictorOptions po;
    po.variables = static_cast<int>(selected_.size());
    po.history = run_.cim.history;
    po.units = method == "cim-mlp" ? run_.cim.mlp_encoder_units : run_.cim.encoder_units;
    po.hidden = run_.cim.hidden;
    predictor_ = SpeedPredictor(po);
    load_module_bytes(*predictor_, read_file_bytes(dir + "/" + kCimPredictorFile), torch::kCPU,
                      dir + "/" + kCimPredictorFile);
    predictor_->eval();
    input_ = torch::zeros({1, po.variables, po.history});
    view_buf_ = torch::zeros({1, 1, kVaeSize, kVaeSize});
    if (!s.eval.cim_path.empty()) {
      if (!free_)
        throw ConfigError("eval.cim_path is the path a free-steering cim steers along: it needs "
                          "ego.lateral = \"free\"");
      const std::optional<DimRun> path_run = read_dim_run(s.eval.cim_path);
      if (!path_run)
        throw DataError("eval.cim_path: " + s.eval.cim_path + " holds no dim/rip run (no " +
                        kDimJson + "; train one with `causaldrive train --method dim`)");
      path_ = make_agent(path_run->method, s.eval.cim_path, s, world);
    }
  }

  std::string name() const override { return method_; }
  int history() const override { return run_.cim.history; }
  int history_stride() const override { return run_.cim.history_stride; }
  double goal_distance() const override { return path_ ? path_->goal_distance() : 0.0; }
  void begin_episode() override {
    pid_.reset();
    target_ = std::nan("");
    cache_.clear();
    if (path_) path_->begin_episode();
  }

  Control act(const Observation& obs) override {
    check_observation(method_, obs, run_.channels, run_.height, run_.width, history());
    torch::NoGradGuard no_grad;
    float* in = input_.data_ptr<float>();
    const int H = history(), V = static_cast<int>(selected_.size());
    for (int k = 0; k < H; ++k) {
      const std::vector<float>& mu = mu_of(obs.frames[k]);
      for (int v = 0; v < V; ++v) in[v * H + k] = mu[selected_[v]];
    }
    target_ = std::max(0.0, static_cast<double>(predictor_->forward(input_).item<float>()));
    Control c = pid_.control(target_, obs.speed);
    if (!free_) return c;
    if (path_) {
      // The planner sees the current frame (its history is 1) and the same odometry and goal.
      Observation now = obs;
      now.frames.assign(1, obs.frames.back());
      c.steer = path_->act(now).steer;
    } else if (world_) {
      c.steer = steer_towards_path(*world_);
    }
    return c;
  }

  // The path model's own figures (dim/rip: how far its planner moves the plans), if any.
  nlohmann::json episode_figures() const override {
    return path_ ? path_->episode_figures() : nlohmann::json::object();
  }

  double last_target_speed() const override { return target_; }
  bool steers() const override { return true; }  // along the route (ego.lateral = "free")
  bool steers_from_world() const override { return free_ && !path_; }

 private:
  // mu of one frame, one image at a time (so a frame's mu never depends on its batch). The
  // views of the last few frames are remembered: with history_stride 1 each step encodes only
  // the new frame. Keys are the whole view, so a hit is exact.
  const std::vector<float>& mu_of(const uint8_t* frame) {
    std::vector<float> view(kVaeSize * kVaeSize);
    view_from_planes(view_, frame, view.data());
    for (const auto& [v, mu] : cache_)
      if (v == view) return mu;
    std::memcpy(view_buf_.data_ptr<float>(), view.data(), view.size() * sizeof(float));
    torch::Tensor mu = vae_->encode(view_buf_).first.contiguous();
    std::vector<float> m(mu.data_ptr<float>(), mu.data_ptr<float>() + mu.numel());
    const size_t keep = static_cast<size_t>(history() * history_stride() + 1);
    while (cache_.size() >= keep) cache_.pop_front();
    cache_.emplace_back(std::move(view), std::move(m));
    return cache_.back().second;
  }

  std::string method_;
  bool free_;           // ego.lateral = "free": the agent steers
  const World* world_;  // the route's geometry, for a free-steering ego's path tracker
  std::unique_ptr<Agent> path_;  // eval.cim_path's dim/rip agent: the path it steers along
  CimRunInfo run_;
  GreyView view_;
  std::vector<int> selected_;
  BetaVae vae_;
  SpeedPredictor predictor_{nullptr};
  SpeedPid pid_;
  torch::Tensor input_, view_buf_;
  std::deque<std::pair<std::vector<float>, std::vector<float>>> cache_;
  double target_ = std::nan("");
};

}  // namespace

std::unique_ptr<Agent> load_cim_agent(const std::string& method, const std::string& dir,
                                      const Settings& settings, const World* world) {
  set_torch_threads(1);
  return std::make_unique<CimAgent>(method, dir, settings, world);
}

void cim_entangled_settings(Settings& s) { s.vae.beta = 1.0; }  // the plain VAE of the ablation

}  // namespace cd
