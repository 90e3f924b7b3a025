#pragma once
// A trained family policy (bc-so, bc-oh, residual, fca, keyframe, hd, dagger) acting in a
// MuJoCo-Image env from rendered frames: what `eval --env` runs and what dagger's rollouts mix
// with the expert. It keeps the episode's frames and feeds the network K of them `stride` steps
// apart (the checkpoint's history), oldest first; its action is clamped to the ctrlrange.
#include <memory>
#include <string>
#include <vector>

#include "mujoco/env.hpp"

namespace cd {
class PolicyRunner;
}

namespace cd::mj {

class FramePolicy {
 public:
  // Loads the run folder's best weights with torch on one thread (one worker per core). Throws
  // DataError for a missing or damaged checkpoint, ConfigError for another method.
  // `device`: eval.device (auto | cpu | cuda), resolved at the first action.
  FramePolicy(const std::string& run_dir, const std::string& method,
              const std::string& device = "cpu");
  ~FramePolicy();
  FramePolicy(const FramePolicy&) = delete;
  FramePolicy& operator=(const FramePolicy&) = delete;

  int width() const;   // of the frames it was trained on: render at this size
  int height() const;

  void begin_episode();         // forgets the frames
  void push(Frame frame);       // the frame after reset or after a step
  // Whether K real frames are held ((K - 1) * stride steps since the episode began): until
  // then the caller acts otherwise (never a repeated or blank frame).
  bool ready() const;
  // The action for the latest frame; `previous` is the action executed one step before
  // (residual's memory-only controller reads it), `low`/`high` the env's ctrlrange.
  std::vector<double> act(const std::vector<double>& previous, const std::vector<double>& low,
                          const std::vector<double>& high);

 private:
  std::unique_ptr<PolicyRunner> runner_;
  std::vector<Frame> frames_;
  std::vector<const uint8_t*> history_;
  std::vector<float> previous_;
};

}  // namespace cd::mj
