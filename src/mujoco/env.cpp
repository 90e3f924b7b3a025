#include "mujoco/env.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <mujoco/mujoco.h>

#include "core/error.hpp"
#include "mujoco/renderer.hpp"

namespace cd::mj {

Env::Env(const std::string& name, const EnvOptions& options)
    : spec_(env_spec(name)), options_(options) {
  if (options_.width < 1 || options_.height < 1 || options_.width > 4096 ||
      options_.height > 4096) {
    throw ConfigError("frame size " + std::to_string(options_.width) + "x" +
                      std::to_string(options_.height) + " for env '" + name +
                      "' must be within 1..4096");
  }
  model_ = load_model(assets_dir(options_.assets_dir) + "/" + spec_.model_file);
  data_ = mj_makeData(model_.get());
  if (data_ == nullptr) throw SimError("cannot allocate MuJoCo data for env '" + name + "'");
  recompute();
}

Env::~Env() {
  renderer_.reset();
  if (data_ != nullptr) mj_deleteData(data_);
}

double Env::dt() const { return model_->opt.timestep * spec_.frame_skip; }
int Env::action_dim() const { return model_->nu; }
int Env::state_dim() const { return model_->nq + model_->nv; }
int Env::qpos_dim() const { return model_->nq; }

std::vector<double> Env::action_low() const {
  std::vector<double> low(model_->nu);
  for (int i = 0; i < model_->nu; ++i) low[i] = model_->actuator_ctrlrange[2 * i];
  return low;
}

std::vector<double> Env::action_high() const {
  std::vector<double> high(model_->nu);
  for (int i = 0; i < model_->nu; ++i) high[i] = model_->actuator_ctrlrange[2 * i + 1];
  return high;
}

void Env::recompute() {
  mj_forward(model_.get(), data_);
  // cfrc_ext is filled only by the post-constraint pass, which mj_step skips.
  if (spec_.contact_forces) mj_rnePostConstraint(model_.get(), data_);
}

Frame Env::reset(uint64_t seed) {
  mj_resetData(model_.get(), data_);  // qpos0, zero velocity, time 0
  Rng rng(seed);
  spec_.reset_noise(*model_, *data_, rng);
  steps_ = 0;
  recompute();
  return render();
}

StepResult Env::step(std::span<const double> action) {
  const mjModel* m = model_.get();
  if (static_cast<int>(action.size()) != m->nu) {
    throw SimError("env '" + spec_.name + "' takes " + std::to_string(m->nu) +
                   " action values, got " + std::to_string(action.size()));
  }
  for (double a : action)
    if (!std::isfinite(a)) throw SimError("env '" + spec_.name + "' got a non-finite action");
  const double before = spec_.progress(*m, *data_);
  for (int i = 0; i < m->nu; ++i) data_->ctrl[i] = action[i];
  for (int k = 0; k < spec_.frame_skip; ++k) mj_step(m, data_);
  // mj_step leaves positions of the last substep's start: recompute them for the new state, so
  // that rewards, terminations and frames all describe the state the step ends in.
  recompute();
  ++steps_;
  StepResult r;
  r.reward = spec_.reward(*m, *data_, before, action, dt());
  r.terminated = spec_.healthy != nullptr && !spec_.healthy(*m, *data_);
  r.truncated = !r.terminated && steps_ >= spec_.max_steps;
  return r;
}

std::vector<double> Env::state() const {
  std::vector<double> s(state_dim());
  for (int i = 0; i < model_->nq; ++i) s[i] = data_->qpos[i];
  for (int i = 0; i < model_->nv; ++i) s[model_->nq + i] = data_->qvel[i];
  return s;
}

void Env::set_state(std::span<const double> state) {
  if (static_cast<int>(state.size()) != state_dim()) {
    throw SimError("env '" + spec_.name + "' has a state of " + std::to_string(state_dim()) +
                   " values (qpos then qvel), got " + std::to_string(state.size()));
  }
  for (int i = 0; i < model_->nq; ++i) data_->qpos[i] = state[i];
  for (int i = 0; i < model_->nv; ++i) data_->qvel[i] = state[model_->nq + i];
  // The solver's warm start would carry the previous trajectory into the next step: clear it,
  // so that what follows a set_state depends on the state alone.
  for (int i = 0; i < model_->nv; ++i) data_->qacc_warmstart[i] = 0;
  recompute();
}

namespace {
// The mjData arrays a snapshot holds after time and the step counter, with their lengths.
std::vector<std::pair<double*, int>> integration_arrays(const mjModel& m, mjData& d) {
  return {{d.qpos, m.nq}, {d.qvel, m.nv}, {d.act, m.na}, {d.ctrl, m.nu}, {d.qacc_warmstart, m.nv}};
}
}  // namespace

std::vector<double> Env::snapshot() const {
  std::vector<double> s = {data_->time, static_cast<double>(steps_)};
  for (auto [p, n] : integration_arrays(*model_, *data_)) s.insert(s.end(), p, p + n);
  return s;
}

void Env::restore(std::span<const double> s) {
  size_t want = 2;
  for (auto [p, n] : integration_arrays(*model_, *data_)) want += static_cast<size_t>(n);
  if (s.size() != want)
    throw SimError("env '" + spec_.name + "' has snapshots of " + std::to_string(want) +
                   " values, got " + std::to_string(s.size()));
  data_->time = s[0];
  steps_ = static_cast<int>(s[1]);
  size_t k = 2;
  for (auto [p, n] : integration_arrays(*model_, *data_)) {
    std::copy_n(s.begin() + static_cast<std::ptrdiff_t>(k), n, p);
    k += static_cast<size_t>(n);
  }
  recompute();
}

void Env::render(uint8_t* out) {
  if (!renderer_) {
    renderer_ = std::make_unique<OffscreenRenderer>(*model_, options_.width, options_.height);
  }
  renderer_->render(*model_, *data_, spec_.camera, out);
}

Frame Env::render() {
  Frame f(frame_bytes());
  render(f.data());
  return f;
}

}  // namespace cd::mj
