#pragma once
// How an agent is fed from a World, step by step: a ring of the frames it needs (history()
// frames, history_stride() steps apart, newest last; nothing is rendered for an agent that
// uses no frames) and the Observation of the current state. The benchmark runner and dagger's
// closed-loop rollouts drive agents through it. With a sensor shift (eval.sensor = "shifted"),
// frame n of the episode is rendered through it with the key sensor_frame_key(shift seed,
// episode_key, n), so reruns and workers see the same noise.
#include <cstdint>

#include "agents/agent.hpp"
#include "core/frame_buffer.hpp"
#include "sense/sensor_shift.hpp"

namespace cd {

class World;

class ObservationFeed {
 public:
  ObservationFeed(const World& world, const Agent& agent, const SensorShift* shift = nullptr,
                  uint64_t episode_key = 0);

  // Renders the current state's frame into the ring.
  void push();
  // Frames rendered so far.
  size_t rendered() const { return rendered_; }
  // Steps of rendering needed before the first full history (span - 1 before the current).
  size_t span() const { return span_; }
  bool ready() const { return !frames_ || rendered_ >= span_; }
  // The observation of the current state (after push()): the ring's frames, speed, command,
  // pose and, for agents with a goal distance, the route goal.
  const Observation& observe();

 private:
  const World& world_;
  const SensorShift* shift_;
  uint64_t episode_key_;
  int k_, stride_;
  bool frames_;
  double goal_distance_;
  size_t span_, frame_bytes_, rendered_ = 0;
  FrameBytes ring_;
  Observation obs_;
};

}  // namespace cd
