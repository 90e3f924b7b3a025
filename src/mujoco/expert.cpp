#include "mujoco/expert.hpp"

#include <filesystem>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "mujoco/sac.hpp"

namespace cd::mj {

std::unique_ptr<Expert> make_expert(const std::string& env, const PlannerOptions& planner,
                                    const std::string& policies) {
  if (policies.empty()) return std::make_unique<PlannerExpert>(env, planner);
  return std::make_unique<PolicyExpert>(policies + "/" + env + ".pt", env);
}

std::string expert_policies_for(const std::string& setting, const std::string& env,
                                const PlannerOptions& p) {
  if (setting == "planner") return "";
  if (!setting.empty()) return setting;
  const PlannerOptions d;
  if (p.samples != d.samples || p.horizon != d.horizon || p.iterations != d.iterations ||
      p.sigma != d.sigma || p.temperature != d.temperature || p.smoothing != d.smoothing ||
      p.terminal_steps != d.terminal_steps)
    return "";  // a tuned planner was asked for
  const std::string shipped = std::string(CD_SOURCE_DIR) + "/experts";
  return std::filesystem::exists(shipped + "/" + env + ".pt") ? shipped : "";
}

PlannerOptions planner_options(const MujocoSettings& m) {
  PlannerOptions o;
  o.samples = m.planner_samples;
  o.horizon = m.planner_horizon;
  o.iterations = m.planner_iterations;
  o.sigma = m.planner_sigma;
  o.temperature = m.planner_temperature;
  o.smoothing = m.planner_smoothing;
  o.terminal_steps = m.planner_terminal_steps;
  return o;
}

PlannerOptions planner_defaults(const std::string& env, PlannerOptions o) {
  struct Default {
    const char* env;
    int samples, horizon, iterations;
    double sigma, temperature, smoothing, terminal_steps;
  };
  // Chosen for a 2-core CPU: the cost of a query is samples x horizon x iterations env steps.
  // Tuned on short closed-loop runs (`causaldrive bench expert`, README "MuJoCo-Image"):
  // halfcheetah gains most from wide noise, greedy weights and a terminal speed bonus; reacher
  // from a second, finer iteration; humanoid from a longer horizon (16 steps fell at step 77)
  // with smooth, smaller noise; hopper keeps no terminal bonus (with one it falls).
  static const Default table[] = {
      {"halfcheetah", 64, 20, 1, 0.8, 0.05, 0.0, 10.0},
      {"hopper", 64, 48, 1, 0.4, 0.1, 0.0, 0.0},
      {"ant", 48, 16, 1, 0.5, 0.05, 0.0, 10.0},
      {"reacher", 64, 25, 2, 0.3, 0.1, 0.0, 0.0},
      {"humanoid", 64, 32, 1, 0.2, 0.05, 0.5, 0.0},
  };
  const Default* d = nullptr;
  for (const Default& entry : table)
    if (env == entry.env) d = &entry;
  if (d == nullptr) env_spec(env);  // throws the one-line unknown-env error
  if (d == nullptr) throw ConfigError("no planner defaults for env '" + env + "'");
  if (o.samples <= 0) o.samples = d->samples;
  if (o.horizon <= 0) o.horizon = d->horizon;
  if (o.iterations <= 0) o.iterations = d->iterations;
  if (o.sigma <= 0) o.sigma = d->sigma;
  if (o.temperature <= 0) o.temperature = d->temperature;
  if (o.smoothing < 0) o.smoothing = d->smoothing;
  if (o.terminal_steps < 0) o.terminal_steps = d->terminal_steps;
  if (o.smoothing >= 1) throw ConfigError("planner smoothing must be below 1");
  return o;
}

PlannerExpert::PlannerExpert(const std::string& env, const PlannerOptions& options)
    : sim_(env), options_(planner_defaults(env, options)), low_(sim_.action_low()),
      high_(sim_.action_high()), dim_(sim_.action_dim()), rng_(options_.seed) {
  reset();
}

void PlannerExpert::reset() { mean_.assign(static_cast<size_t>(options_.horizon) * dim_, 0.0); }

std::string PlannerExpert::describe() const {
  char line[224];
  std::snprintf(line, sizeof line,
                "mppi samples=%d horizon=%d iterations=%d sigma=%g temperature=%g smoothing=%g "
                "terminal_steps=%g",
                options_.samples, options_.horizon, options_.iterations, options_.sigma,
                options_.temperature, options_.smoothing, options_.terminal_steps);
  return line;
}

double PlannerExpert::rollout(std::span<const double> state, const std::vector<double>& plan) {
  sim_.set_state(state);
  double total = 0, last = 0;
  for (int h = 0; h < options_.horizon; ++h) {
    const StepResult r = sim_.step(std::span<const double>(plan.data() + h * dim_, dim_));
    ++simulated_steps_;
    total += r.reward;
    last = r.reward;
    if (r.terminated) {
      // Falling ends Gym's episode: worse than any reward a rollout can gain on the way down,
      // and the sooner the worse.
      return total - 1000.0 - 10.0 * (options_.horizon - h);
    }
  }
  return total + options_.terminal_steps * last;
}

// plan = mean + noise, clamped; the noise of each action component an AR(1) process along the
// horizon with unit variance (smoothing 0: white).
void PlannerExpert::sample_noise(std::vector<double>& plan, double sigma) {
  const double b = options_.smoothing, fresh = std::sqrt(1.0 - b * b);
  std::vector<double> e(dim_);
  for (int h = 0; h < options_.horizon; ++h) {
    for (int j = 0; j < dim_; ++j) {
      const double n = standard_normal(rng_);
      e[j] = h == 0 ? n : b * e[j] + fresh * n;
      const size_t i = static_cast<size_t>(h) * dim_ + j;
      const double half = 0.5 * (high_[j] - low_[j]);
      plan[i] = std::clamp(mean_[i] + sigma * half * e[j], low_[j], high_[j]);
    }
  }
}

std::vector<double> PlannerExpert::act(std::span<const double> state) {
  const int k_count = options_.samples, h_count = options_.horizon;
  const size_t plan_size = static_cast<size_t>(h_count) * dim_;
  std::vector<std::vector<double>> plans(k_count, std::vector<double>(plan_size));
  std::vector<double> returns(k_count);
  for (int it = 0; it < options_.iterations; ++it) {
    // Later iterations refine: the noise halves each time.
    const double sigma = options_.sigma * std::pow(0.5, it);
    for (int k = 0; k < k_count; ++k) {
      // Sample 0 is the current plan itself, so a good plan is never lost to noise.
      if (k == 0)
        plans[k] = mean_;
      else
        sample_noise(plans[k], sigma);
      returns[k] = rollout(state, plans[k]);
    }
    const double best = *std::max_element(returns.begin(), returns.end());
    const double worst = *std::min_element(returns.begin(), returns.end());
    const double scale = options_.temperature * std::max(best - worst, 1e-9);
    double total = 0;
    std::vector<double> next(plan_size, 0.0);
    for (int k = 0; k < k_count; ++k) {
      const double w = std::exp((returns[k] - best) / scale);
      total += w;
      for (size_t i = 0; i < plan_size; ++i) next[i] += w * plans[k][i];
    }
    for (size_t i = 0; i < plan_size; ++i) mean_[i] = next[i] / total;
  }
  std::vector<double> action(mean_.begin(), mean_.begin() + dim_);
  // Warm start: the plan moves one step forward, its last step repeated.
  std::rotate(mean_.begin(), mean_.begin() + dim_, mean_.end());
  if (h_count > 1)
    for (int j = 0; j < dim_; ++j) mean_[plan_size - dim_ + j] = mean_[plan_size - 2 * dim_ + j];
  return action;
}

}  // namespace cd::mj
