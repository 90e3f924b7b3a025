#pragma once
// The "new sensor" condition of the failure-mode tables (SPEC section 5, `eval.sensor =
// "shifted"`): our stand-in for seed 001's new weather, an appearance shift of the BEV that no
// training frame has: seeded, deterministic perception noise.
//
// Where it acts: on the road users before rasterising (a box is a perception output, so
// misses, position errors and ghosts are edits of the list of boxes, drawn by the one box
// rasteriser), and on the lane-marking channel after it (the paint is pre-rasterised per town,
// so wear is erased from the rendered plane). The route and the traffic-light channels are left
// as they are: the shift changes how reliable the road users and the paint look, never what the
// task is. Values stay 0/255.
//
// Determinism: a frame's boxes depend on (seed, frame_key) only, where the runner's frame key
// is sensor_frame_key(seed, the episode's traffic seed (one per task and trial), frame number);
// worn paint is fixed on the road (cells of kFadeCell m in the network frame, drawn from the
// seed alone), so it stays put while the ego drives past, as real worn paint does.
#include <cstdint>
#include <string>

#include "sense/bev.hpp"

namespace cd {

inline constexpr double kFadeCell = 2.0;            // m, side of a worn-or-not paint cell
inline constexpr double kHeadingJitterPerM = 0.1;   // rad of heading error per m of jitter_m
inline constexpr double kGhostPedestrianShare = 0.25;  // of ghost boxes; the rest are cars
inline constexpr double kGhostCarLength = 4.5, kGhostCarWidth = 1.8, kGhostPedSize = 0.5;

// Strengths of the shift ([eval] sensor_* keys).
struct SensorShift {
  uint64_t seed = 0;      // sensor_seed
  double miss = 0.15;     // sensor_miss: probability that a vehicle or pedestrian is not drawn
  double jitter_m = 0.5;  // sensor_jitter_m: sd of a drawn box's position error (m), per frame
  double ghosts = 0.5;    // sensor_ghosts: expected ghost boxes per frame (Poisson), in view
  double fade = 0.4;      // sensor_fade: share of the lane-marking paint worn away
};

// The key of frame `frame` (0-based, history prefill included) of the episode `episode_key`.
uint64_t sensor_frame_key(uint64_t seed, uint64_t episode_key, uint64_t frame);

// The boxes the shifted sensor reports: each vehicle and pedestrian missed with probability
// `miss`, the others moved by N(0, jitter_m) in x and y and turned by N(0, jitter_m *
// kHeadingJitterPerM); then Poisson(ghosts) ghost boxes uniform over the view (`cfg` around
// scene.ego), uniform heading. Stop lines and the ego are kept.
BevScene shift_scene(const BevScene& scene, const SensorShift& shift, const BevConfig& cfg,
                     uint64_t frame_key);

// Erases the worn paint from the marking plane of a rendered C x H x W frame seen from `ego`:
// a marking pixel is erased when its centre lies in a worn cell (share `fade`).
void fade_markings(uint8_t* frame, const BevConfig& cfg, const Pose2& ego,
                   const SensorShift& shift);

// The frame an agent sees: renderer.render(scene) with the clean sensor (shift == nullptr), the
// shifted scene rendered and its paint worn otherwise.
void render_sensor(const BevRenderer& renderer, const BevScene& scene, const SensorShift* shift,
                   uint64_t frame_key, uint8_t* out);

// The shift draws on the BEV: ConfigError for `view` "camera", whose new-sensor condition is a
// held-out weather (sense.camera.weather).
void require_bev_for_shift(const std::string& view);

}  // namespace cd
