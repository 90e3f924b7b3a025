#include "agents/agent.hpp"

#include "core/error.hpp"

namespace cd {

std::string frame_shape(int channels, int height, int width) {
  return std::to_string(channels) + "x" + std::to_string(height) + "x" + std::to_string(width);
}

void check_observation(const std::string& agent, const Observation& obs, int channels, int height,
                       int width, int history) {
  if (obs.channels != channels || obs.height != height || obs.width != width)
    throw ConfigError("agent '" + agent + "' was trained on " + frame_shape(channels, height, width) +
                      " BEV frames but is given " + frame_shape(obs.channels, obs.height, obs.width) +
                      ": use the [bev] settings of its training data");
  if (static_cast<int>(obs.frames.size()) != history)
    throw Error("agent '" + agent + "' needs " + std::to_string(history) +
                " frames per observation, got " + std::to_string(obs.frames.size()));
}

}  // namespace cd
