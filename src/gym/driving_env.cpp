#include "gym/driving_env.hpp"

#include <cmath>

#include "collect/expert_episode.hpp"
#include "core/error.hpp"
#include "world/town.hpp"

namespace cd {

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool is_town(const std::string& name) {
  if (ends_with(name, ".net.xml")) return true;
  for (const std::string& t : town_names())
    if (t == name) return true;
  return false;
}

}  // namespace

DrivingEnv::DrivingEnv(const std::string& name, const Settings& settings)
    : settings_(settings), expert_(settings.expert) {
  if (is_town(name)) {
    settings_.world.town = name;
  } else {
    bool builtin = false;
    for (const std::string& s : builtin_suite_names()) builtin = builtin || s == name;
    if (!builtin && !ends_with(name, ".json")) {
      std::string known;
      for (const std::string& s : builtin_suite_names()) known += (known.empty() ? "" : ", ") + s;
      for (const std::string& t : town_names()) known += ", " + t;
      throw ConfigError("unknown environment '" + name + "': not a suite (" + known +
                        ", or a suite .json file), a town or a .net.xml network");
    }
    suite_ = load_suite(name);
    settings_.world.town = suite_->town;
    settings_.world.traffic = suite_->traffic;
    trials_ = settings_.eval.trials > 0 ? settings_.eval.trials : suite_->trials;
  }
  world_ = std::make_unique<World>(settings_);
}

DrivingEnv::~DrivingEnv() = default;

int DrivingEnv::episodes() const {
  return suite_ ? static_cast<int>(suite_->tasks.size()) * trials_ : 0;
}

void DrivingEnv::reset(std::optional<uint64_t> seed, int episode) {
  Task task;
  if (suite_) {
    const int n = episodes();
    if (n == 0) throw ConfigError("suite " + suite_->name + " has no tasks");
    if (episode >= n)
      throw ConfigError("episode " + std::to_string(episode) + " is out of range: suite " +
                        suite_->name + " has " + std::to_string(n) + " episodes");
    if (episode < 0) episode = seed ? static_cast<int>(*seed % static_cast<uint64_t>(n))
                                    : next_episode_;
    episode_ = episode;
    next_episode_ = (episode + 1) % n;
    task = suite_episode_task(*suite_, trials_, episode);
    seed_ = task.traffic_seed;
  } else {
    if (episode >= 0)
      throw ConfigError("an environment on a town draws its tasks from seeds: no episode index");
    seed_ = seed ? *seed : cd::episode_seed(settings_.collect.seed, resets_);
    episode_ = -1;
    task = collect_task(*world_, settings_.collect, seed_);
  }
  ++resets_;
  running_ = false;
  world_->reset(task);
  scorer_ = std::make_unique<EpisodeScorer>(*world_, task, settings_.world.dt);
  result_ = EpisodeResult{};
  running_ = started_ = true;
}

EnvStep DrivingEnv::step(const Control& c) {
  if (!running_)
    throw Error(started_ ? "step() after the episode ended: call reset() first"
                         : "step() before reset()");
  if (!std::isfinite(c.throttle) || !std::isfinite(c.brake))
    throw ConfigError("the action holds a value that is not finite");
  const double before = world_->ego().progress;
  EnvStep s;
  s.result = world_->step(c);
  scorer_->observe(*world_, s.result);
  s.reward = world_->ego().progress - before;
  if (s.result.outcome == Outcome::Collision) s.reward -= kCollisionPenalty;
  if (s.result.outcome != Outcome::Running) {
    running_ = false;
    result_ = scorer_->finish(*world_, s.result);
    result_.index = std::max(episode_, 0);
    if (suite_) {
      result_.task = episode_ / trials_;
      result_.trial = episode_ % trials_;
    }
    s.terminated = s.result.outcome != Outcome::Timeout;
    s.truncated = !s.terminated;
  }
  return s;
}

Control DrivingEnv::expert_action() const {
  if (!started_) throw Error("expert_action() before reset()");
  return expert_.act(*world_);
}

}  // namespace cd
