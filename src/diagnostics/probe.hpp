#pragma once
// The copycat probe of a history policy (bc-oh): does the policy read "am I moving?" from its
// history instead of the scene? On recorded frames where the ego stands still (speed below
// 0.5 m/s) with a full real history, the policy's output is compared for three histories
// behind the same current frame:
//   real    the recorded frames;
//   moving  synthetic frames of the scene as it would have looked had the ego been driving
//           toward it at `moving_speed`, the ego moving_speed * L * dt metres behind its place
//           at lag L steps, the rest of the scene as it is now:
//           the BEV ("shifted"): the current frame with its content moved up the image (up =
//             ahead, sense/bev.hpp) by round(moving_speed * L * dt / metres_per_pixel) pixels,
//             rows left uncovered at the bottom set to 0;
//           the front camera ("replayed"): the scene drawn again from the pose that far behind
//             the one the frame was drawn from (the ego's, or collect.augment's shifted pose)
//             on its heading (pose_behind). A camera frame has no metric scale to move,
//             so the probe replays the folder's episodes: collection is deterministic for an
//             episode's seed, and with collect.json's settings the expert, its noise and the
//             traffic drive each episode again; at a probed frame the world holds the recorded
//             state, and the replay's frame is checked byte for byte against the recorded
//             one. Vehicles stay where they are now, as in the BEV's shift (one behind the ego
//             within those metres may then stand in front of the camera);
//   static  the current frame repeated.
// A policy that copies its own past motion accelerates under "moving" and stays put under
// "static" whatever the scene: the history effect mean |out(moving) - out(static)| measures
// it, separately where the path is free (ground truth causes/path_free = 1: going is right)
// and where it is blocked (going is a collision). The output is the target speed (m/s) for a
// target_speed head, throttle - brake for a throttle_brake head.
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "core/geometry.hpp"

namespace cd {

struct ProbeOptions {
  std::string checkpoint;     // a `causaldrive train` folder of a history policy
  std::string data;           // a `causaldrive collect` folder
  long max_frames = 0;        // > 0: at most this many stopped frames, spread evenly
  double moving_speed = 5.0;  // m/s of the synthetic moving history
  double stopped_below = 0.5; // m/s: the ego counts as stopped below this speed
};

struct ProbeGroup {
  long count = 0;
  double mean_real = 0, mean_moving = 0, mean_static = 0;
  double history_effect = 0;       // mean |out(moving) - out(static)|
  double moving_minus_static = 0;  // mean out(moving) - out(static)
};

struct ProbeReport {
  std::string checkpoint, data, method, output;  // output: target_speed | throttle_minus_brake
  int history = 0, stride = 0;
  double moving_speed = 0, stopped_below = 0, dt = 0, metres_per_pixel = 0;
  std::string moving_history;  // shifted (BEV) | replayed (front camera)
  long replayed_episodes = 0;  // the camera: episodes driven again
  long frames = 0;          // frames in the data folder
  long stopped_frames = 0;  // stopped with a full history
  long probed_frames = 0;   // of those, probed (max_frames)
  ProbeGroup path_free, blocked;
};

// Throws ConfigError for a policy without history (K == 1) or MuJoCo-Image data, DataError for
// missing or damaged checkpoint or data, data whose frame format differs from the checkpoint's,
// or (the camera) a folder without collect.json or whose replay does not give its frames.
ProbeReport run_probe(const ProbeOptions& options);

nlohmann::json probe_report_json(const ProbeReport& report);
std::string probe_report_table(const ProbeReport& report);

// `pose` moved `metres` back along its heading.
Pose2 pose_behind(const Pose2& pose, double metres);

// The synthetic moving history's frame at lag `shift` pixels: C planes of H x W bytes of
// `current` moved up by `shift` rows, the bottom `shift` rows zero.
void shift_frame_up(const unsigned char* current, int channels, int height, int width, int shift,
                    unsigned char* out);

}  // namespace cd
