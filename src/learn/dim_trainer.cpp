#include "learn/dim_trainer.hpp"

// Maximum-likelihood training of the DIM density (nn/dim_net.hpp), one member after the
// other (rip: dim.ensemble members, each on a bootstrap resample of the training episodes).
//
// Samples: every step t of every episode with t + horizon*waypoint_step < T; labels are the
// future positions, inputs frame t and the past positions, all in the ego frame of t
// (learn/dim_run.hpp). Validation holds out whole episodes (choose_val_episodes);
// train.max_samples keeps a seeded subset of both splits, shrunk by the same fraction.
// Randomness of member k (weights, bootstrap, shuffling of epoch n) comes from (train.seed, k,
// n) only, so a member retrained after an interruption gives the same bytes.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <ATen/Parallel.h>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "learn/dataset.hpp"
#include "learn/dim_run.hpp"
#include "learn/methods.hpp"
#include "nn/dim_net.hpp"

namespace cd {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

constexpr uint64_t kSubsetStream = 0x5ab5e7d1;
constexpr uint64_t kBootstrapStream = 0xb0075;
constexpr uint64_t kWeightStream = 0x3e1917;
constexpr uint64_t kShuffleStream = 0x5f1e;

// Keys that may change between runs into the same folder: where the output goes and the
// compute resources (the bytes are the same for the same train.threads).
bool may_differ(const std::string& table, const std::string& key) {
  if (table == "dim")  // the planner's settings: used by the agents only
    return key == "plan_iterations" || key == "plan_lr" || key == "goal_distance" ||
           key == "goal_weight" || key == "replan_steps" || key == "aggregation";
  return table == "train" && (key == "out" || key == "threads" || key == "device");
}

// n of v chosen by a seeded partial shuffle, kept in their original order.
std::vector<SampleRef> subset(const std::vector<SampleRef>& v, size_t n, Rng& rng) {
  if (n >= v.size()) return v;
  std::vector<size_t> idx(v.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  for (size_t i = 0; i < n; ++i) std::swap(idx[i], idx[i + rng.below(idx.size() - i)]);
  idx.resize(n);
  std::sort(idx.begin(), idx.end());
  std::vector<SampleRef> out;
  out.reserve(n);
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

struct Samples {
  std::vector<SampleRef> train, val;
  std::vector<int> val_episodes, train_episodes;
};

Samples make_samples(const EpisodeSet& eps, const Settings& s) {
  const DimSettings& d = s.dim;
  const int n = static_cast<int>(eps.episodes.size());
  Samples out;
  out.val_episodes = choose_val_episodes(n, s.train.val_fraction, s.train.seed);
  const int reach = d.horizon * d.waypoint_step;
  for (int e = 0; e < n; ++e) {
    const bool val = std::binary_search(out.val_episodes.begin(), out.val_episodes.end(), e);
    if (!val) out.train_episodes.push_back(e);
    for (int t = 0; t + reach < eps.episodes[e].frames; ++t)
      (val ? out.val : out.train).push_back({e, t});
  }
  const size_t total = out.train.size() + out.val.size();
  const long max = s.train.max_samples;
  if (max > 0 && static_cast<size_t>(max) < total) {
    const double keep = static_cast<double>(max) / static_cast<double>(total);
    size_t nv = out.val.empty() ? 0 : std::max<size_t>(1, std::lround(keep * out.val.size()));
    nv = std::min(nv, static_cast<size_t>(max));
    Rng rng(derive_seed(s.train.seed, kSubsetStream));
    out.train = subset(out.train, static_cast<size_t>(max) - nv, rng);
    out.val = subset(out.val, nv, rng);
  }
  if (out.train.empty())
    throw DataError("data folder '" + eps.dir + "' leaves no dim training sample (episodes " +
                    "need more than dim.horizon * dim.waypoint_step = " + std::to_string(reach) +
                    " steps; " + std::to_string(out.val.size()) + " validation samples)");
  return out;
}

// Member k of rip: as many training episodes drawn with replacement as there are, and the
// (kept) samples of each draw; dim trains on every training sample.
std::vector<SampleRef> member_samples(const Samples& all, const std::string& method,
                                      uint64_t seed, int member, std::vector<int>& draws) {
  draws.clear();
  if (method != "rip") return all.train;
  Rng rng(derive_seed(seed ^ kBootstrapStream, static_cast<uint64_t>(member)));
  const size_t n = all.train_episodes.size();
  std::vector<SampleRef> out;
  for (size_t i = 0; i < n; ++i) {
    const int e = all.train_episodes[rng.below(n)];
    draws.push_back(e);
    // all.train is sorted by episode: its samples of e are one range.
    auto lo = std::lower_bound(all.train.begin(), all.train.end(), e,
                               [](const SampleRef& s, int ep) { return s.episode < ep; });
    for (auto it = lo; it != all.train.end() && it->episode == e; ++it) out.push_back(*it);
  }
  if (out.empty()) return all.train;  // every draw hit an episode without kept samples
  return out;
}

struct Batch {
  torch::Tensor frames, past, future;

  Batch(const EpisodeSet& eps, const DimSettings& d, int capacity) {
    frames = torch::empty({capacity, eps.channels, eps.height, eps.width});
    past = torch::empty({capacity, d.past, 2});
    future = torch::empty({capacity, d.horizon, 2});
  }

  void fill(const EpisodeSet& eps, const DimSettings& d, const std::vector<SampleRef>& samples,
            const std::vector<uint32_t>* order, size_t begin, int64_t n) {
    float* f = frames.data_ptr<float>();
    float* p = past.data_ptr<float>();
    float* z = future.data_ptr<float>();
    const size_t fv = eps.frame_values();
    // Each sample writes its own rows: the result does not depend on the thread count.
    at::parallel_for(0, n, 8, [&](int64_t lo, int64_t hi) {
      for (int64_t i = lo; i < hi; ++i) {
        const size_t k = begin + static_cast<size_t>(i);
        const SampleRef& s = samples[order ? (*order)[k] : k];
        eps.planes01(s.episode, s.t, f + i * fv);
        dim_sample_positions(eps.episodes[s.episode], s.t, d, p + i * 2 * d.past,
                             z + i * 2 * d.horizon);
      }
    });
  }
};

torch::Tensor batch_nll(DimNet& net, const Batch& b, int64_t n, const torch::Device& device) {
  auto on = [&](const torch::Tensor& t) { return t.narrow(0, 0, n).to(device); };
  torch::Tensor features = net->encode(on(b.frames));
  return -net->log_prob(features, on(b.past), on(b.future)).mean();
}

void print_line(bool quiet, const std::string& line) {
  if (quiet) return;
  // On a terminal the progress line is redrawn in place: clear it first.
  std::fprintf(stderr, "%s%s\n", isatty(STDERR_FILENO) ? "\r\033[K" : "", line.c_str());
  std::fflush(stderr);
}

}  // namespace

TrainSummary train_dim(const Settings& settings_in, const TrainRequest& req) {
  const auto run_start = Clock::now();
  check_train_method(req.method);
  if (req.method != "dim" && req.method != "rip")
    throw ConfigError("train_dim trains dim or rip, not '" + req.method + "'");
  const Settings s = effective_settings(req.method, settings_in);
  if (req.out_dir.empty()) throw ConfigError("train: no output folder given (--out)");
  const std::string out = req.out_dir;
  const std::string data_dir = canonical_dir(req.data_dir);
  const json settings_json = settings_to_json(s);
  const DimSettings& d = s.dim;

  // A folder that holds another run is refused before any data is read.
  refuse_other_method_folder(out, req.method);
  std::optional<DimRun> previous = read_dim_run(out);
  if (previous) {
    if (previous->method != req.method)
      throw ConfigError(out + " holds a run of method '" + previous->method + "', not '" +
                        req.method + "': train into another --out folder");
    const std::string diff =
        settings_diff(previous->settings, settings_json, {"dim", "train"}, may_differ);
    if (!diff.empty())
      throw ConfigError(out + " holds a " + req.method + " run trained with other settings (" +
                        diff + "): train into another --out folder, or delete it to start over");
    if (previous->data_dir != data_dir)
      throw ConfigError(out + " holds a run trained on " + previous->data_dir + ", not " +
                        data_dir + ": train into another --out folder");
  }

  const std::string device_name = resolve_device(s.train.device);
  const torch::Device device(device_name == "cuda" ? torch::kCUDA : torch::kCPU);
  torch::set_num_threads(s.train.threads);

  const EpisodeSet eps = load_episode_set(req.data_dir);
  for (const auto& e : eps.episodes)
    if (e.pose.size() != 3 * static_cast<size_t>(e.frames))
      throw DataError(req.data_dir + "/" + e.file + " has no pose (T x 3) series: dim needs it");
  const Samples samples = make_samples(eps, s);

  DimRun run;
  if (previous) {
    run = *previous;
    if (run.train_samples != static_cast<long>(samples.train.size()) ||
        run.val_samples != static_cast<long>(samples.val.size()) ||
        run.input.channels != eps.channels || run.input.height != eps.height ||
        run.input.width != eps.width)
      throw ConfigError(out + " holds a run trained on other data than " + data_dir +
                        " now gives: the data changed; train into another --out folder");
  } else {
    run.method = req.method;
    run.settings = settings_json;
    run.dim = d;
    run.input = {eps.channels, eps.height, eps.width, 1, 1, eps.dt, eps.metres_per_pixel,
                 eps.channel_names};
    run.data_dir = data_dir;
    run.train_samples = static_cast<long>(samples.train.size());
    run.val_samples = static_cast<long>(samples.val.size());
    run.train_episodes = static_cast<int>(samples.train_episodes.size());
    run.val_episodes = static_cast<int>(samples.val_episodes.size());
    for (int k = 0; k < d.ensemble; ++k) {
      DimMember m;
      m.index = k;
      run.members.push_back(m);
    }
  }
  run.device = device_name;

  TrainSummary sum;
  sum.method = req.method;
  sum.out_dir = out;
  sum.device = device_name;
  sum.train_samples = run.train_samples;
  sum.val_samples = run.val_samples;
  sum.train_episodes = run.train_episodes;
  sum.val_episodes = run.val_episodes;
  sum.has_validation = run.val_samples > 0;
  sum.weights_file = run.members.size() > 1 ? "member_*.pt" : dim_member_file(0);
  for (const DimMember& m : run.members)
    if (m.finished) sum.resumed_from += static_cast<int>(m.metrics.size());

  fs::create_directories(out);
  remove_stale_temporaries(out);
  write_file_atomic(out + "/" + kDimJson, dim_run_to_json(run).dump(2) + "\n");

  const DimNetOptions no = dim_net_options(d, eps.channels, eps.height, eps.width);

  const int epochs = s.train.epochs;
  const int B = s.train.batch_size;
  const size_t n_val = samples.val.size();
  Batch batch(eps, d, B);
  long to_train = 0;
  std::vector<std::vector<SampleRef>> member_train(run.members.size());
  for (DimMember& m : run.members) {
    if (m.finished) continue;
    member_train[m.index] =
        member_samples(samples, req.method, s.train.seed, m.index, m.episodes);
    to_train += static_cast<long>(member_train[m.index].size()) * epochs;
  }
  std::optional<Progress> progress;
  if (!req.quiet && to_train > 0) progress.emplace("train " + req.method, to_train);
  long trained_now = 0;
  double train_seconds_now = 0;

  for (DimMember& m : run.members) {
    if (m.finished) continue;
    const std::vector<SampleRef>& train = member_train[m.index];
    const size_t n_train = train.size();
    m.train_samples = static_cast<long>(n_train);
    m.metrics.clear();
    m.best_epoch = 0;
    m.best_nll = 0;
    const uint64_t member_seed = derive_seed(s.train.seed, static_cast<uint64_t>(m.index));

    torch::manual_seed(derive_seed(member_seed, kWeightStream));
    DimNet net(no);
    net->to(device);
    torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(s.train.lr));
    std::string best_bytes;

    for (int epoch = 1; epoch <= epochs; ++epoch) {
      const auto epoch_start = Clock::now();
      Rng rng(derive_seed(member_seed ^ kShuffleStream, static_cast<uint64_t>(epoch)));
      std::vector<uint32_t> order(n_train);
      for (size_t i = 0; i < n_train; ++i) order[i] = static_cast<uint32_t>(i);
      for (size_t i = n_train; i > 1; --i) std::swap(order[i - 1], order[rng.below(i)]);

      net->train();
      double nll_sum = 0;
      for (size_t begin = 0; begin < n_train; begin += B) {
        const int64_t n = std::min<int64_t>(B, static_cast<int64_t>(n_train - begin));
        batch.fill(eps, d, train, &order, begin, n);
        torch::Tensor loss = batch_nll(net, batch, n, device);
        opt.zero_grad();
        loss.backward();
        // The NLL of a badly placed sample can be huge while sigma is small: bound the step.
        torch::nn::utils::clip_grad_norm_(net->parameters(), 10.0);
        opt.step();
        const double v = loss.item<double>();
        nll_sum += v * static_cast<double>(n);
        if (progress) {
          char note[96];
          std::snprintf(note, sizeof note, "member %d/%d epoch %d/%d nll %.3f", m.index + 1,
                        d.ensemble, epoch, epochs, v);
          progress->advance(n, note);
        }
      }
      const double train_s = std::chrono::duration<double>(Clock::now() - epoch_start).count();

      std::optional<double> val_nll;
      if (n_val > 0) {
        torch::NoGradGuard no_grad;
        net->eval();
        double total = 0;
        for (size_t begin = 0; begin < n_val; begin += B) {
          const int64_t n = std::min<int64_t>(B, static_cast<int64_t>(n_val - begin));
          batch.fill(eps, d, samples.val, nullptr, begin, n);
          total += batch_nll(net, batch, n, device).item<double>() * static_cast<double>(n);
        }
        val_nll = total / static_cast<double>(n_val);
      }

      DimEpochMetrics em;
      em.member = m.index;
      em.epoch = epoch;
      em.train_nll = nll_sum / static_cast<double>(n_train);
      em.val_nll = val_nll;
      em.lr = s.train.lr;
      em.samples_per_s = train_s > 0 ? static_cast<double>(n_train) / train_s : 0.0;
      em.seconds = std::chrono::duration<double>(Clock::now() - epoch_start).count();
      m.metrics.push_back(em);
      trained_now += static_cast<long>(n_train);
      train_seconds_now += train_s;

      const double selection = val_nll.value_or(em.train_nll);
      if (m.best_epoch == 0 || selection < m.best_nll) {
        m.best_epoch = epoch;
        m.best_nll = selection;
        net->to(torch::kCPU);
        best_bytes = save_module_bytes(*net);
        net->to(device);
      }
      char line[200];
      std::snprintf(line, sizeof line,
                    "%s member %d/%d epoch %d/%d: train nll %.4f, val nll %s, %.0f samples/s",
                    req.method.c_str(), m.index + 1, d.ensemble, epoch, epochs, em.train_nll,
                    val_nll ? std::to_string(*val_nll).c_str() : "-", em.samples_per_s);
      print_line(req.quiet, line);
    }

    // Commit the member: its weights, then the record that says it is finished.
    write_file_atomic(out + "/" + dim_member_file(m.index), best_bytes);
    m.finished = true;
    write_file_atomic(out + "/" + kDimJson, dim_run_to_json(run).dump(2) + "\n");
    write_file_atomic(out + "/" + kMetricsJsonl, dim_metrics_jsonl(run));
  }
  if (progress) progress->finish();
  // Regenerated also when nothing was left to train.
  write_file_atomic(out + "/" + kMetricsJsonl, dim_metrics_jsonl(run));

  for (const DimMember& m : run.members) sum.epochs_done += static_cast<int>(m.metrics.size());
  sum.best_epoch = run.members.front().best_epoch;
  sum.best_loss = run.members.front().best_nll;
  sum.seconds = std::chrono::duration<double>(Clock::now() - run_start).count();
  sum.samples_per_s = train_seconds_now > 0 ? trained_now / train_seconds_now : 0.0;
  return sum;
}

}  // namespace cd
