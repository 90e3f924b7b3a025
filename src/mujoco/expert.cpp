#include "mujoco/expert.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"

namespace cd::mj {

PlannerOptions planner_defaults(const std::string& env, PlannerOptions o) {
  struct Default {
    const char* env;
    int samples, horizon, iterations;
    double sigma;
  };
  // Chosen for a 2-core CPU: the cost of a query is samples x horizon x iterations env steps.
  static const Default table[] = {
      {"halfcheetah", 64, 16, 1, 0.5}, {"hopper", 64, 48, 1, 0.4}, {"ant", 48, 16, 1, 0.5},
      {"reacher", 64, 25, 1, 0.3},     {"humanoid", 64, 16, 1, 0.3},
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
  if (o.temperature <= 0) throw ConfigError("planner temperature must be positive");
  return o;
}

PlannerExpert::PlannerExpert(const std::string& env, const PlannerOptions& options)
    : sim_(env), options_(planner_defaults(env, options)), low_(sim_.action_low()),
      high_(sim_.action_high()), dim_(sim_.action_dim()), rng_(options_.seed) {
  reset();
}

void PlannerExpert::reset() { mean_.assign(static_cast<size_t>(options_.horizon) * dim_, 0.0); }

std::string PlannerExpert::describe() const {
  char line[160];
  std::snprintf(line, sizeof line, "mppi samples=%d horizon=%d iterations=%d sigma=%g temperature=%g",
                options_.samples, options_.horizon, options_.iterations, options_.sigma,
                options_.temperature);
  return line;
}

double PlannerExpert::rollout(std::span<const double> state, const std::vector<double>& plan) {
  sim_.set_state(state);
  double total = 0;
  for (int h = 0; h < options_.horizon; ++h) {
    const StepResult r = sim_.step(std::span<const double>(plan.data() + h * dim_, dim_));
    ++simulated_steps_;
    total += r.reward;
    if (r.terminated) {
      // Falling ends Gym's episode: worse than any reward a rollout can gain on the way down.
      total -= 1000.0;
      break;
    }
  }
  return total;
}

std::vector<double> PlannerExpert::act(std::span<const double> state) {
  const int k_count = options_.samples, h_count = options_.horizon;
  const size_t plan_size = static_cast<size_t>(h_count) * dim_;
  std::vector<std::vector<double>> plans(k_count, std::vector<double>(plan_size));
  std::vector<double> returns(k_count);
  for (int it = 0; it < options_.iterations; ++it) {
    for (int k = 0; k < k_count; ++k) {
      std::vector<double>& p = plans[k];
      for (size_t i = 0; i < plan_size; ++i) {
        const size_t j = i % dim_;
        const double half = 0.5 * (high_[j] - low_[j]);
        // Sample 0 is the current plan itself, so a good plan is never lost to noise.
        const double noise = k == 0 ? 0.0 : options_.sigma * half * standard_normal(rng_);
        p[i] = std::clamp(mean_[i] + noise, low_[j], high_[j]);
      }
      returns[k] = rollout(state, p);
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
