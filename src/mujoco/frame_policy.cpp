#include "mujoco/frame_policy.hpp"

#include <algorithm>

#include "inference/policy_runner.hpp"

namespace cd::mj {

FramePolicy::FramePolicy(const std::string& run_dir, const std::string& method,
                         const std::string& device) {
  set_torch_threads(1);
  runner_ = std::make_unique<PolicyRunner>(run_dir, method, kBestFile, device);
  history_.resize(static_cast<size_t>(runner_->history()));
}

FramePolicy::~FramePolicy() = default;

int FramePolicy::width() const { return runner_->checkpoint().input.width; }
int FramePolicy::height() const { return runner_->checkpoint().input.height; }

void FramePolicy::begin_episode() { frames_.clear(); }

void FramePolicy::push(Frame frame) { frames_.push_back(std::move(frame)); }

bool FramePolicy::ready() const {
  const size_t need = static_cast<size_t>((runner_->history() - 1) * runner_->stride()) + 1;
  return frames_.size() >= need;
}

std::vector<double> FramePolicy::act(const std::vector<double>& previous,
                                     const std::vector<double>& low,
                                     const std::vector<double>& high) {
  const int K = runner_->history(), stride = runner_->stride();
  const size_t t = frames_.size() - 1;
  for (int k = 0; k < K; ++k)
    history_[static_cast<size_t>(k)] = frames_[t - static_cast<size_t>((K - 1 - k) * stride)].data();
  previous_.assign(previous.begin(), previous.end());
  runner_->run(history_.data(), 0.0, 0, previous_.data());
  const std::vector<float>& a = runner_->last_action();
  std::vector<double> out(low.size());
  for (size_t j = 0; j < out.size(); ++j) out[j] = std::clamp<double>(a[j], low[j], high[j]);
  return out;
}

}  // namespace cd::mj
