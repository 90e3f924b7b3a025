// The cim family in closed loop: the history frames' grey views -> the VAE's mu -> the
// selected latents (all of them for cim-mlp) -> the speed predictor -> target speed (>= 0)
// -> SpeedPid (seed 000 eq. 2). The path is the route the ego follows (no lateral control).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>

#include <nlohmann/json.hpp>

#include "agents/learned_agents.hpp"
#include "control/pid.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "learn/cim_data.hpp"
#include "learn/policy_runner.hpp"
#include "nn/beta_vae.hpp"
#include "nn/policy_net.hpp"
#include "nn/speed_predictor.hpp"

namespace cd {

namespace {

class CimAgent : public Agent {
 public:
  CimAgent(const std::string& method, const std::string& dir, const Settings& s)
      : method_(method),
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
  }

  std::string name() const override { return method_; }
  int history() const override { return run_.cim.history; }
  int history_stride() const override { return run_.cim.history_stride; }
  void begin_episode() override {
    pid_.reset();
    target_ = std::nan("");
    cache_.clear();
  }

  Control act(const Observation& obs, const World&) override {
    if (obs.channels != run_.channels || obs.height != run_.height || obs.width != run_.width)
      throw ConfigError("agent '" + method_ + "' was trained on " + shape(run_.channels, run_.height,
                        run_.width) + " BEV frames but is given " +
                        shape(obs.channels, obs.height, obs.width) + ": use the [bev] settings "
                        "of its training data");
    if (static_cast<int>(obs.frames.size()) != history())
      throw Error("agent '" + method_ + "' needs " + std::to_string(history()) +
                  " frames per observation, got " + std::to_string(obs.frames.size()));
    torch::NoGradGuard no_grad;
    float* in = input_.data_ptr<float>();
    const int H = history(), V = static_cast<int>(selected_.size());
    for (int k = 0; k < H; ++k) {
      const std::vector<float>& mu = mu_of(obs.frames[k]);
      for (int v = 0; v < V; ++v) in[v * H + k] = mu[selected_[v]];
    }
    target_ = std::max(0.0, static_cast<double>(predictor_->forward(input_).item<float>()));
    return pid_.control(target_, obs.speed);
  }

  double last_target_speed() const override { return target_; }

 private:
  static std::string shape(int c, int h, int w) {
    return std::to_string(c) + "x" + std::to_string(h) + "x" + std::to_string(w);
  }

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
  CimRunInfo run_;
  CimView view_;
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
                                      const Settings& settings) {
  set_torch_threads(1);
  return std::make_unique<CimAgent>(method, dir, settings);
}

}  // namespace cd
