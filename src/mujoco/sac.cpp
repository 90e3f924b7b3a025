#include "mujoco/sac.hpp"

#include <torch/torch.h>
#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "device/device.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rng.hpp"
#include "mujoco/env.hpp"
#include "nn/policy_net.hpp"

namespace cd::mj {

namespace {

struct MlpImpl : torch::nn::Module {
  MlpImpl(int in, int hidden, int out)
      : l1(register_module("l1", torch::nn::Linear(in, hidden))),
        l2(register_module("l2", torch::nn::Linear(hidden, hidden))),
        l3(register_module("l3", torch::nn::Linear(hidden, out))) {}
  torch::Tensor forward(const torch::Tensor& x) {
    return l3(torch::relu(l2(torch::relu(l1(x)))));
  }
  torch::nn::Linear l1, l2, l3;
};
TORCH_MODULE(Mlp);

constexpr double kLogStdMin = -20, kLogStdMax = 2;

// The actor: a squashed Gaussian over actions in [-1, 1]^A.
struct ActorImpl : torch::nn::Module {
  ActorImpl(int obs, int act, int hidden) : act_dim(act), net(register_module("net", Mlp(obs, hidden, 2 * act))) {}
  std::pair<torch::Tensor, torch::Tensor> mean_log_std(const torch::Tensor& obs) {
    auto out = net(obs).chunk(2, -1);
    return {out[0], out[1].clamp(kLogStdMin, kLogStdMax)};
  }
  torch::Tensor deterministic(const torch::Tensor& obs) { return torch::tanh(mean_log_std(obs).first); }
  // A reparameterised draw and its log-probability (tanh's change of variables included).
  std::pair<torch::Tensor, torch::Tensor> sample(const torch::Tensor& obs) {
    auto [mean, log_std] = mean_log_std(obs);
    const torch::Tensor u = mean + log_std.exp() * torch::randn_like(mean);
    const torch::Tensor gauss = (-0.5 * ((u - mean) / log_std.exp()).pow(2) - log_std -
                                 0.5 * std::log(2 * M_PI)).sum(-1);
    // log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)), stable for large |u|.
    const torch::Tensor squash =
        (2 * (std::log(2.0) - u - torch::nn::functional::softplus(-2 * u))).sum(-1);
    return {torch::tanh(u), gauss - squash};
  }
  int act_dim;
  Mlp net;
};
TORCH_MODULE(Actor);

// Two Q functions of (observation, action).
struct CriticImpl : torch::nn::Module {
  CriticImpl(int obs, int act, int hidden)
      : q1(register_module("q1", Mlp(obs + act, hidden, 1))),
        q2(register_module("q2", Mlp(obs + act, hidden, 1))) {}
  std::pair<torch::Tensor, torch::Tensor> forward(const torch::Tensor& obs, const torch::Tensor& act) {
    const torch::Tensor x = torch::cat({obs, act}, -1);
    return {q1(x).squeeze(-1), q2(x).squeeze(-1)};
  }
  Mlp q1, q2;
};
TORCH_MODULE(Critic);

void copy_params(torch::nn::Module& to, torch::nn::Module& from, double tau) {
  torch::NoGradGuard no_grad;
  auto t = to.parameters(), f = from.parameters();
  for (size_t i = 0; i < t.size(); ++i) t[i].mul_(1 - tau).add_(f[i], tau);
}

// Env action (ctrlrange) from a policy action in [-1, 1].
std::vector<double> to_env(std::span<const float> a, const std::vector<double>& low,
                           const std::vector<double>& high) {
  std::vector<double> out(a.size());
  for (size_t i = 0; i < a.size(); ++i) out[i] = low[i] + (a[i] + 1.0) * 0.5 * (high[i] - low[i]);
  return out;
}

void validate(const SacOptions& o) {
  auto bad = [](const std::string& what) { throw ConfigError("sac: " + what); };
  if (o.steps < 1) bad("steps must be >= 1");
  if (o.start_steps < 0 || o.start_steps > o.steps) bad("start_steps must be in [0, steps]");
  if (o.batch < 1) bad("batch must be >= 1");
  if (o.hidden < 1) bad("hidden must be >= 1");
  if (!(o.lr > 0)) bad("lr must be > 0");
  if (!(o.gamma > 0 && o.gamma <= 1)) bad("gamma must be in (0, 1]");
  if (!(o.tau > 0 && o.tau <= 1)) bad("tau must be in (0, 1]");
  if (o.eval_every < 1) bad("eval_every must be >= 1");
  if (o.eval_episodes < 1) bad("eval_episodes must be >= 1");
  if (o.threads < 1) bad("threads must be >= 1");
}

// The file: the actor's parameters and its sizes (obs, act, hidden), so that it loads alone.
void save_actor(Actor& actor, int obs, int act, int hidden, const std::string& env,
                const std::string& path) {
  torch::serialize::OutputArchive archive;
  // Host tensors: the file loads on a machine without a GPU.
  const torch::Device where = actor->parameters().front().device();
  actor->to(torch::kCPU);
  actor->save(archive);
  actor->to(where);
  archive.write("sizes", torch::tensor({int64_t(obs), int64_t(act), int64_t(hidden)}));
  archive.write("env_" + env, torch::zeros({1}));
  // Through memory: a file archive would carry its (temporary) file name inside.
  std::ostringstream bytes;
  archive.save_to(bytes);
  write_file_atomic(path, bytes.str());
}

}  // namespace

std::vector<float> policy_input(const EnvSpec& spec, int nq, std::span<const double> state) {
  std::vector<float> x;
  x.reserve(state.size());
  for (size_t i = static_cast<size_t>(std::min(spec.position_dims, nq)); i < state.size(); ++i)
    x.push_back(static_cast<float>(state[i]));
  return x;
}

namespace {

// The run's options as recorded; `with_steps` false leaves out what may grow on a resume.
nlohmann::json options_json(const SacOptions& o, bool with_steps = true) {
  nlohmann::json j = {{"start_steps", o.start_steps}, {"batch", o.batch}, {"hidden", o.hidden},
                      {"lr", o.lr}, {"gamma", o.gamma}, {"tau", o.tau},
                      {"eval_every", o.eval_every}, {"eval_episodes", o.eval_episodes},
                      {"seed", o.seed}, {"threads", o.threads}};
  if (with_steps) j["steps"] = o.steps;
  return j;
}

nlohmann::json evaluation_json(const SacEvaluation& e) {
  return {{"steps", e.steps}, {"mean_return", e.mean_return}, {"sd_return", e.sd_return},
          {"seconds", e.seconds}};
}

SacEvaluation evaluation_from(const nlohmann::json& j) {
  SacEvaluation e;
  e.steps = j.at("steps").get<long>();
  e.mean_return = j.at("mean_return").get<double>();
  e.sd_return = j.at("sd_return").get<double>();
  e.seconds = j.value("seconds", 0.0);
  return e;
}

torch::Tensor bytes_tensor(const std::string& s) {
  return torch::from_blob(const_cast<char*>(s.data()), {static_cast<int64_t>(s.size())}, torch::kUInt8)
      .clone();
}

std::string tensor_bytes(const torch::Tensor& t) {
  const torch::Tensor c = t.to(torch::kUInt8).contiguous();
  return {reinterpret_cast<const char*>(c.data_ptr<uint8_t>()), static_cast<size_t>(c.numel())};
}

// A finished run's record at `out`'s JSON with these options: its report; nullopt otherwise.
std::optional<SacReport> finished_run(const std::string& json_path, const std::string& env,
                                      const SacOptions& o) {
  try {
    const nlohmann::json j = nlohmann::json::parse(read_file_bytes(json_path));
    if (j.at("env") != env || j.at("options") != options_json(o)) return std::nullopt;
    SacReport r;
    for (const auto& e : j.at("evaluations")) r.evaluations.push_back(evaluation_from(e));
    if (r.evaluations.empty() || r.evaluations.back().steps != o.steps) return std::nullopt;
    r.best = evaluation_from(j.at("best"));
    r.seconds = j.at("seconds").get<double>();
    r.episodes = j.at("episodes").get<long>();
    return r;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::string sac_resume_path(const std::string& out) { return out + ".resume"; }

SacReport train_sac(const std::string& env_name, const SacOptions& o, const std::string& out,
                    const std::function<void(const std::string&)>& log) {
  validate(o);
  Env env(env_name);
  Env eval_env(env_name);
  const EnvSpec& spec = env.spec();
  const int nq = env.qpos_dim(), A = env.action_dim();
  const int O = static_cast<int>(policy_input(spec, nq, env.state()).size());
  const std::vector<double> low = env.action_low(), high = env.action_high();
  const std::string record_path = std::filesystem::path(out).replace_extension(".json").string();
  const std::string resume_path = sac_resume_path(out);
  const bool resuming = std::filesystem::exists(resume_path);
  if (!resuming && std::filesystem::exists(out)) {
    // Rerunning a finished run is a no-op; anything else would overwrite a policy.
    if (std::optional<SacReport> done = finished_run(record_path, env_name, o)) {
      if (log) log("[sac " + env_name + "] " + out + " is finished with these options: kept");
      return *done;
    }
    throw ConfigError(out + " already exists and its record " + record_path +
                      " is not a finished run with these options (nor is there a resume file " +
                      resume_path + "); delete it or choose another --out");
  }
  if (!std::filesystem::path(out).parent_path().empty())
    std::filesystem::create_directories(std::filesystem::path(out).parent_path());

  const ComputeDevice dev = compute_device(o.device, "fp32", false, o.threads, "--device");
  const torch::Device D = dev.device;
  torch::set_num_threads(o.threads);
  torch::manual_seed(o.seed);
  Actor actor(O, A, o.hidden);
  Critic critic(O, A, o.hidden), target(O, A, o.hidden);
  copy_params(*target, *critic, 1.0);
  for (auto& p : target->parameters()) p.set_requires_grad(false);
  actor->to(D);
  critic->to(D);
  target->to(D);
  torch::Tensor log_alpha = torch::zeros({1}, torch::TensorOptions().device(D).requires_grad(true));
  // An observation (host floats) on the networks' device, and an action back on the host.
  auto on_device = [&](std::vector<float>& x) {
    return torch::from_blob(x.data(), {1, O}).clone().to(D);
  };
  torch::optim::Adam actor_opt(actor->parameters(), o.lr), critic_opt(critic->parameters(), o.lr),
      alpha_opt({log_alpha}, o.lr);
  const double target_entropy = -static_cast<double>(A);

  // Replay buffer: every transition of the run.
  const int64_t N = o.steps;
  torch::Tensor b_obs = torch::zeros({N, O}), b_next = torch::zeros({N, O}),
                b_act = torch::zeros({N, A}), b_rew = torch::zeros({N}), b_done = torch::zeros({N});
  std::vector<std::pair<std::string, torch::Tensor*>> buffers = {
      {"b_obs", &b_obs}, {"b_next", &b_next}, {"b_act", &b_act}, {"b_rew", &b_rew}, {"b_done", &b_done}};
  std::vector<std::pair<std::string, torch::nn::Module*>> modules = {
      {"actor", actor.get()}, {"critic", critic.get()}, {"target", target.get()}};
  std::vector<std::pair<std::string, torch::optim::Optimizer*>> optimizers = {
      {"actor_opt", &actor_opt}, {"critic_opt", &critic_opt}, {"alpha_opt", &alpha_opt}};

  Rng rng(derive_seed(o.seed, 1));
  long episodes = 0;
  auto start_episode = [&] { env.reset(derive_seed(derive_seed(o.seed, 2), uint64_t(episodes++))); };
  start_episode();
  std::vector<float> obs = policy_input(spec, nq, env.state());

  auto evaluate = [&](long steps_done) {
    torch::NoGradGuard no_grad;
    std::vector<double> returns;
    for (int k = 0; k < o.eval_episodes; ++k) {
      eval_env.reset(derive_seed(derive_seed(o.seed, 3), uint64_t(k)));
      double ret = 0;
      for (int t = 0; t < eval_env.max_steps(); ++t) {
        std::vector<float> x = policy_input(spec, nq, eval_env.state());
        torch::Tensor a = actor->deterministic(on_device(x)).to(torch::kCPU)[0];
        const StepResult r = eval_env.step(to_env({a.data_ptr<float>(), size_t(A)}, low, high));
        ret += r.reward;
        if (r.terminated || r.truncated) break;
      }
      returns.push_back(ret);
    }
    SacEvaluation e;
    e.steps = steps_done;
    for (double r : returns) e.mean_return += r / returns.size();
    for (double r : returns) e.sd_return += (r - e.mean_return) * (r - e.mean_return) / returns.size();
    e.sd_return = std::sqrt(e.sd_return);
    return e;
  };

  SacReport report;
  report.best.mean_return = -1e300;
  double seconds_before = 0;  // training time of earlier sessions of a resumed run
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return seconds_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  auto evaluations_json = [&] {
    nlohmann::json evals = nlohmann::json::array();
    for (const SacEvaluation& e : report.evaluations) evals.push_back(evaluation_json(e));
    return evals;
  };
  auto write_record = [&] {
    nlohmann::json j = {
        {"env", env_name}, {"algorithm", "sac"}, {"options", options_json(o)},
        {"best", {{"steps", report.best.steps}, {"mean_return", report.best.mean_return},
                  {"sd_return", report.best.sd_return}}},
        {"episodes", episodes}, {"seconds", elapsed()}, {"evaluations", evaluations_json()},
        {"runtime", dev.record()}};
    write_file_atomic(record_path, j.dump(2) + "\n");
  };

  // The resume file, written at every evaluation: networks, optimisers, temperature, the
  // buffer so far, both random streams and the training env's exact state, so that a resumed
  // run continues bit for bit (same bytes as a run never stopped).
  auto save_resume = [&](long steps_done) {
    torch::serialize::OutputArchive archive;
    const nlohmann::json meta = {{"env", env_name},        {"options", options_json(o, false)},
                                 {"steps_done", steps_done}, {"episodes", episodes},
                                 {"seconds", elapsed()},     {"best", evaluation_json(report.best)},
                                 {"evaluations", evaluations_json()}, {"rng", rng.state()}};
    archive.write("meta", bytes_tensor(meta.dump()));
    for (auto& [name, m] : modules) archive.write(name, bytes_tensor(save_module_bytes(*m)));
    for (auto& [name, opt] : optimizers) archive.write(name, bytes_tensor(save_optimizer_bytes(*opt)));
    archive.write("log_alpha", log_alpha.detach().to(torch::kCPU).clone());
    for (auto& [name, b] : buffers) archive.write(name, b->narrow(0, 0, steps_done).clone());
    {
      // The engine's state, and both cached normal draws set explicitly on loading, so that
      // restoring does not depend on how get_state's legacy layout carries them.
      auto gen = at::detail::getDefaultCPUGenerator();
      std::lock_guard<std::mutex> lock(gen.mutex());
      archive.write("torch_rng", gen.get_state());
      auto* impl = gen.get<at::CPUGeneratorImpl>();
      nlohmann::json cached = {{"double", nullptr}, {"float", nullptr}};
      if (auto d = impl->next_double_normal_sample()) cached["double"] = *d;
      if (auto f = impl->next_float_normal_sample()) cached["float"] = static_cast<double>(*f);
      archive.write("torch_rng_cached", bytes_tensor(cached.dump()));
    }
    const std::vector<double> snap = env.snapshot();
    archive.write("env_state", torch::tensor(snap, torch::kFloat64));
    std::ostringstream bytes;
    archive.save_to(bytes);
    write_file_atomic(resume_path, bytes.str());
  };
  // Returns the env steps the resume file had done.
  auto load_resume = [&]() -> long {
    const std::string hint = "; delete " + resume_path + " to start over";
    try {
      torch::serialize::InputArchive archive;
      archive.load_from(resume_path);
      // A fresh tensor per key: reading into a defined tensor would keep its dtype.
      auto read = [&](const std::string& key) {
        torch::Tensor x;
        archive.read(key, x);
        return x;
      };
      torch::Tensor t = read("meta");
      const nlohmann::json meta = nlohmann::json::parse(tensor_bytes(t));
      if (meta.at("env") != env_name || meta.at("options") != options_json(o, false))
        throw ConfigError(resume_path + " belongs to a run with other settings (" +
                          meta.at("env").get<std::string>() + ", " + meta.at("options").dump() +
                          "); rerun with those" + hint);
      const long done = meta.at("steps_done").get<long>();
      if (done > o.steps)
        throw ConfigError(resume_path + " is at step " + std::to_string(done) + ", past --steps " +
                          std::to_string(o.steps));
      for (auto& [name, m] : modules) {
        t = read(name);
        load_module_bytes(*m, tensor_bytes(t), D, resume_path + " (" + name + ")");
      }
      for (auto& [name, opt] : optimizers) {
        t = read(name);
        load_optimizer_bytes(*opt, tensor_bytes(t), D, resume_path + " (" + name + ")", hint);
      }
      t = read("log_alpha");
      {
        torch::NoGradGuard no_grad;
        log_alpha.copy_(t);
      }
      for (auto& [name, b] : buffers) {
        t = read(name);
        if (t.size(0) != done || t.sizes().slice(1).vec() != b->sizes().slice(1).vec())
          throw DataError(resume_path + ": buffer '" + name + "' has the wrong shape" + hint);
        b->narrow(0, 0, done).copy_(t);
      }
      t = read("torch_rng");
      {
        auto gen = at::detail::getDefaultCPUGenerator();
        std::lock_guard<std::mutex> lock(gen.mutex());
        gen.set_state(t);
        t = read("torch_rng_cached");
        const nlohmann::json cached = nlohmann::json::parse(tensor_bytes(t));
        auto* impl = gen.get<at::CPUGeneratorImpl>();
        impl->set_next_double_normal_sample(
            cached.at("double").is_null() ? c10::optional<double>() : cached["double"].get<double>());
        impl->set_next_float_normal_sample(
            cached.at("float").is_null() ? c10::optional<float>()
                                         : static_cast<float>(cached["float"].get<double>()));
      }
      t = read("env_state");
      const torch::Tensor snap = t.to(torch::kFloat64).contiguous();
      env.restore({snap.data_ptr<double>(), static_cast<size_t>(snap.numel())});
      obs = policy_input(spec, nq, env.state());
      episodes = meta.at("episodes").get<long>();
      seconds_before = meta.at("seconds").get<double>();
      for (const auto& e : meta.at("evaluations")) report.evaluations.push_back(evaluation_from(e));
      report.best = evaluation_from(meta.at("best"));
      rng.set_state(meta.at("rng").get<std::array<uint64_t, 4>>());
      return done;
    } catch (const c10::Error& e) {
      std::string msg = e.what_without_backtrace();
      throw DataError("cannot read the resume file " + resume_path + " (" +
                      msg.substr(0, msg.find('\n')) + ")" + hint);
    } catch (const nlohmann::json::exception& e) {
      throw DataError("cannot read the resume file " + resume_path + " (" + e.what() + ")" + hint);
    } catch (const SimError& e) {
      throw DataError("cannot read the resume file " + resume_path + " (" + e.what() + ")" + hint);
    }
  };

  long first = 0;
  if (resuming) {
    first = load_resume();
    if (log)
      log("[sac " + env_name + "] resuming " + resume_path + " at step " + std::to_string(first) +
          "/" + std::to_string(o.steps));
  }

  std::vector<float> act(static_cast<size_t>(A));
  for (long t = first; t < o.steps; ++t) {
    if (t < o.start_steps) {
      for (float& a : act) a = static_cast<float>(rng.uniform(-1.0, 1.0));
    } else {
      torch::NoGradGuard no_grad;
      torch::Tensor a = actor->sample(on_device(obs)).first.to(torch::kCPU)[0];
      std::copy_n(a.data_ptr<float>(), A, act.begin());
    }
    const StepResult r = env.step(to_env(act, low, high));
    std::vector<float> next = policy_input(spec, nq, env.state());
    std::copy(obs.begin(), obs.end(), b_obs[t].data_ptr<float>());
    std::copy(next.begin(), next.end(), b_next[t].data_ptr<float>());
    std::copy(act.begin(), act.end(), b_act[t].data_ptr<float>());
    b_rew[t] = static_cast<float>(r.reward);
    b_done[t] = r.terminated ? 1.0f : 0.0f;  // a truncated episode still has a future
    if (r.terminated || r.truncated) {
      start_episode();
      obs = policy_input(spec, nq, env.state());
    } else {
      obs = std::move(next);
    }

    if (t + 1 >= o.start_steps && t + 1 >= o.batch) {
      const torch::Tensor idx = torch::randint(0, t + 1, {o.batch}, torch::kLong);
      const torch::Tensor so = b_obs.index_select(0, idx).to(D),
                          sa = b_act.index_select(0, idx).to(D),
                          sr = b_rew.index_select(0, idx).to(D),
                          sn = b_next.index_select(0, idx).to(D),
                          sd = b_done.index_select(0, idx).to(D);
      const torch::Tensor alpha = log_alpha.exp().detach();
      torch::Tensor y;
      {
        torch::NoGradGuard no_grad;
        auto [an, logp_n] = actor->sample(sn);
        auto [t1, t2] = target->forward(sn, an);
        y = sr + o.gamma * (1 - sd) * (torch::min(t1, t2) - alpha * logp_n);
      }
      auto [q1, q2] = critic->forward(so, sa);
      torch::Tensor critic_loss = torch::mse_loss(q1, y) + torch::mse_loss(q2, y);
      critic_opt.zero_grad();
      critic_loss.backward();
      critic_opt.step();

      auto [a_new, logp] = actor->sample(so);
      auto [p1, p2] = critic->forward(so, a_new);
      torch::Tensor actor_loss = (alpha * logp - torch::min(p1, p2)).mean();
      actor_opt.zero_grad();
      actor_loss.backward();
      actor_opt.step();

      torch::Tensor alpha_loss = -(log_alpha * (logp.detach() + target_entropy)).mean();
      alpha_opt.zero_grad();
      alpha_loss.backward();
      alpha_opt.step();
      copy_params(*target, *critic, o.tau);
    }

    if ((t + 1) % o.eval_every == 0 || t + 1 == o.steps) {
      SacEvaluation e = evaluate(t + 1);
      e.seconds = elapsed();
      report.evaluations.push_back(e);
      const bool best = e.mean_return > report.best.mean_return;
      if (best) {
        report.best = e;
        save_actor(actor, O, A, o.hidden, env_name, out);
      }
      report.episodes = episodes;
      write_record();
      // Policy and record first: a run killed before the resume file is rewritten redoes the
      // last stretch from the previous one and writes the same bytes again.
      if (t + 1 < o.steps) save_resume(t + 1);
      if (log) {
        char line[200];
        std::snprintf(line, sizeof line, "[sac %s] %ld/%ld steps  return %.1f +- %.1f%s  alpha %.3f  %s",
                      env_name.c_str(), t + 1, o.steps, e.mean_return, e.sd_return,
                      best ? " (best, saved)" : "", log_alpha.exp().item<double>(),
                      format_duration(e.seconds).c_str());
        log(line);
      }
    }
  }
  report.seconds = elapsed();
  report.episodes = episodes;
  write_record();
  std::filesystem::remove(resume_path);  // finished: the record says so from now on
  return report;
}

struct PolicyExpert::Net {
  Actor actor{nullptr};
  int obs = 0, act = 0;
};

PolicyExpert::PolicyExpert(const std::string& path, const std::string& env)
    : net_(std::make_unique<Net>()), path_(path), spec_(env_spec(env)) {
  Env sim(env);
  nq_ = sim.qpos_dim();
  low_ = sim.action_low();
  high_ = sim.action_high();
  if (!std::filesystem::is_regular_file(path))
    throw DataError("no expert policy for '" + env + "' at " + path);
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(path, torch::kCPU);
    torch::Tensor sizes, tag;
    archive.read("sizes", sizes);
    if (!archive.try_read("env_" + env, tag))
      throw DataError(path + " is an expert policy for another env than '" + env + "'");
    net_->obs = static_cast<int>(sizes[0].item<int64_t>());
    net_->act = static_cast<int>(sizes[1].item<int64_t>());
    const int hidden = static_cast<int>(sizes[2].item<int64_t>());
    const int want_obs = sim.state_dim() - std::min(spec_.position_dims, nq_);
    if (net_->obs != want_obs || net_->act != sim.action_dim())
      throw DataError(path + " expects " + std::to_string(net_->obs) + " inputs and " +
                      std::to_string(net_->act) + " actions; env '" + env + "' has " +
                      std::to_string(want_obs) + " and " + std::to_string(sim.action_dim()));
    net_->actor = Actor(net_->obs, net_->act, hidden);
    net_->actor->load(archive);
    net_->actor->eval();
  } catch (const c10::Error& e) {
    throw DataError("cannot read the expert policy " + path + ": " + e.what_without_backtrace());
  }
}

PolicyExpert::~PolicyExpert() = default;

std::vector<double> PolicyExpert::act(std::span<const double> state) {
  torch::NoGradGuard no_grad;
  std::vector<float> x = policy_input(spec_, nq_, state);
  if (static_cast<int>(x.size()) != net_->obs)
    throw SimError("expert policy " + path_ + " got a state of the wrong size");
  torch::Tensor a = net_->actor->deterministic(torch::from_blob(x.data(), {1, net_->obs}).clone())[0];
  return to_env({a.data_ptr<float>(), size_t(net_->act)}, low_, high_);
}

std::string PolicyExpert::describe() const {
  return "sac policy " + std::filesystem::path(path_).filename().string() + " (deterministic)";
}

}  // namespace cd::mj
