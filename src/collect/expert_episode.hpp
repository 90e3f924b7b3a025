#pragma once
// Drives one episode with the expert and records it (SPEC section 2): the frame before each
// action, the expert's action as the label, the ground-truth causes. With noise injection
// the executed action is replaced for short windows while the label stays the expert's.
#include <cstdint>
#include <functional>
#include <string>

#include "app/settings.hpp"
#include "core/rng.hpp"
#include "data/episode.hpp"
#include "expert/autopilot.hpp"
#include "world/world.hpp"

namespace cd {

struct EpisodeSummary {
  int index = 0;
  std::string outcome;
  long frames = 0;
  double route_length = 0;
  double distance = 0;
  int red_light_violations = 0;
  std::string collided_with;
};

// Names of the recorded causes/ series, in file order.
const std::vector<std::string>& cause_names();

// A recording of a World, step by step (collect's expert episodes, eval --record's agent
// episodes): `data` emptied and shaped for this world's frames (+ steer when the ego steers).
void begin_recording(const World& world, EpisodeData& data);
// Appends the current state: the frame (`stored_frame` when given: what an agent saw or an
// augmented view, as stored: the BEV's H*W bytes of channel bits, the camera's 3*H*W RGB
// bytes; else the world's own), a free ego's lane errors, speed, command, pose and the causes.
// The action is appended apart (record_action).
void record_state(const World& world, EpisodeData& data, const uint8_t* stored_frame = nullptr);
// A frame as recordings store it: the camera's 3*H*W RGB bytes, the BEV's H*W bytes of channel
// bits. stored_frame_bytes: its size; render_stored: the world's frame now, seen from `seen`
// when given (collect.augment's shifted views).
size_t stored_frame_bytes(const World& world);
void render_stored(const World& world, uint8_t* out, const Pose2* seen = nullptr);
// Appends one action: throttle, brake and, when `steers`, steer.
void record_action(EpisodeData& data, const Control& control, bool steers);
// The attributes every recording of this world shares: town, dt, metres per pixel, channel
// and action names, traffic, the code tables; the caller adds suite, seed, outcome, the rest.
EpisodeMeta recording_meta(const World& world, const Settings& settings);

// What drives a recorded episode in place of the expert (dagger's closed-loop rollouts): it is
// told the world when the episode starts and, every step, the expert's label; it returns the
// executed control. The recorded labels stay the expert's; noise injection is off.
class Driver {
 public:
  virtual ~Driver() = default;
  virtual void begin_episode(World& world, uint64_t episode_seed) = 0;
  virtual Control drive(const Control& expert_label) = 0;
  virtual std::string describe() const = 0;  // kept as the episode's "driver" attribute
};

class ExpertRecorder {
 public:
  ExpertRecorder(World& world, const Settings& settings);

  // Samples the task of `episode_seed`, runs it to the end and fills data and meta.
  // With png_dir non-empty, also writes every frame there as PNG.
  // With a driver, it executes the driver's controls.
  EpisodeSummary run(int index, uint64_t episode_seed, EpisodeData& data, EpisodeMeta& meta,
                     const std::string& png_dir = "", Driver* driver = nullptr);

  // The two halves of one recorded step, for loops that drive the world themselves (the
  // throughput benchmark): empty `data` shaped for this world's frames, then append the
  // current frame, measurements, causes and the expert's label, and return that label.
  void begin(EpisodeData& data) const;
  // With `augment` (collect.augment on, a free-steering ego), the frame may come from a shifted
  // pose and its steer label be the correcting one (the returned control stays the expert's).
  Control record_step(EpisodeData& data, Rng* augment = nullptr) const;

  // Called by run() once per recorded step with the step's index, after its frame is recorded
  // and before the world steps: the world then holds the state that frame shows (the camera
  // probe replays a collected episode so, diagnostics/probe.hpp).
  void set_frame_observer(std::function<void(long frame)> observer) {
    observer_ = std::move(observer);
  }

 private:
  World& world_;
  Settings settings_;
  Autopilot expert_;
  std::function<void(long)> observer_;
};

// The seed of episode `index` of a collection run.
uint64_t episode_seed(uint64_t run_seed, int index);

// The task of a collected episode of seed `episode_seed` (its route drawn within the collect
// settings' lengths, its timeout capped by collect.max_episode_s).
Task collect_task(World& world, const CollectSettings& collect, uint64_t episode_seed);

}  // namespace cd
