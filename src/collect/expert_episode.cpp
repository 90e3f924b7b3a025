#include "collect/expert_episode.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/png.hpp"
#include "core/rng.hpp"
#include "sense/bev_colour.hpp"
#include "world/town.hpp"

namespace cd {

namespace {

// Appends the ground-truth causes of the current state, one value per series of the schema.
void record_causes(const GroundTruth& gt, EpisodeData& d) {
  for (const CauseSeries& c : cause_schema())
    d.causes[c.name].push_back(static_cast<float>(c.value(gt)));
}

}  // namespace

const std::vector<std::string>& cause_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const CauseSeries& c : cause_schema()) v.push_back(c.name);
    return v;
  }();
  return names;
}

uint64_t episode_seed(uint64_t run_seed, int index) {
  return derive_seed(run_seed, static_cast<uint64_t>(index));
}

Task collect_task(World& world, const CollectSettings& cs, uint64_t seed) {
  Task task = world.sample_task(derive_seed(seed, 0), cs.min_route_m, cs.max_route_m);
  if (cs.max_episode_s > 0) task.timeout_s = std::min(task.timeout_s, cs.max_episode_s);
  return task;
}

ExpertRecorder::ExpertRecorder(World& world, const Settings& settings)
    : world_(world), settings_(settings), expert_(settings.expert) {}

void begin_recording(const World& world, EpisodeData& d) {
  const FrameFormat& f = world.frame_format();
  d = EpisodeData{};
  d.channels = f.channels;
  d.height = f.height;
  d.width = f.width;
  d.action_dim = world.free_lateral() ? 3 : 2;  // + steer when the ego steers
  for (const auto& name : cause_names()) d.causes[name];  // the series record_causes fills
}

size_t stored_frame_bytes(const World& world) {
  const FrameFormat& f = world.frame_format();
  return world.camera_view() ? f.bytes() : f.pixels();
}

void render_stored(const World& world, uint8_t* out, const Pose2* seen) {
  if (world.camera_view()) {
    if (seen)
      world.render_from(*seen, out);
    else
      world.render(out);
    return;
  }
  BevScene scene = world.scene();
  if (seen) scene.ego = *seen;
  world.renderer().render_packed(scene, out);
}

void record_state(const World& world, EpisodeData& d, const uint8_t* stored_frame) {
  FrameBytes& frames = world.camera_view() ? d.rgb : d.bev_packed;
  const size_t n = stored_frame_bytes(world), at = frames.size();
  frames.resize(at + n);
  if (stored_frame)
    std::copy(stored_frame, stored_frame + n, frames.begin() + at);
  else
    render_stored(world, frames.data() + at);
  if (world.free_lateral()) {
    d.lateral_error.push_back(static_cast<float>(world.road_contact().lateral_error));
    d.heading_error.push_back(static_cast<float>(world.road_contact().heading_error));
  }
  const EgoState& ego = world.ego();
  d.speed.push_back(static_cast<float>(ego.speed));
  d.command.push_back(world.command());
  d.pose.insert(d.pose.end(), {static_cast<float>(ego.pose.pos.x),
                               static_cast<float>(ego.pose.pos.y),
                               static_cast<float>(ego.pose.heading)});
  record_causes(world.truth(), d);
}

void record_action(EpisodeData& d, const Control& c, bool steers) {
  d.action.insert(d.action.end(), {static_cast<float>(c.throttle), static_cast<float>(c.brake)});
  if (steers) d.action.push_back(static_cast<float>(c.steer));
}

EpisodeMeta recording_meta(const World& world, const Settings& settings) {
  EpisodeMeta meta;
  meta.town = network_label(settings.world.town);
  meta.dt = settings.world.dt;
  const FrameFormat& f = world.frame_format();
  meta.metres_per_pixel = f.metres_per_pixel;
  meta.channels = f.channel_names;
  meta.extra["view"] = f.view;
  if (world.camera_view()) meta.extra["weather"] = world.weather();  // this episode's
  meta.action_names = {"throttle", "brake"};
  if (world.free_lateral()) meta.action_names.push_back("steer");
  meta.extra["traffic"] = settings.world.traffic;
  meta.extra["command_codes"] = "0 follow, 1 left, 2 right, 3 straight";
  meta.extra["tl_state_codes"] = "0 none, 1 red, 2 yellow, 3 green, 4 green-yield";
  return meta;
}

void ExpertRecorder::begin(EpisodeData& d) const { begin_recording(world_, d); }

Control ExpertRecorder::record_step(EpisodeData& d, Rng* augment) const {
  // The lateral augmentation: this frame from a shifted, rotated pose, with the steer that
  // corrects it as the label.
  const AugmentSettings& aug = settings_.collect.augment;
  double shift = 0, turn = 0;
  bool augmented = false;
  if (augment && world_.free_lateral()) {
    augmented = augment->uniform() < aug.fraction;
    if (augmented && aug.cameras == "sides") {  // the left camera looks left, the right right
      const double side = augment->uniform() < 0.5 ? 1.0 : -1.0;
      shift = side * aug.shift_m;
      turn = side * aug.rotate_rad;
    } else if (augmented) {
      shift = augment->uniform(-aug.shift_m, aug.shift_m);
      turn = augment->uniform(-aug.rotate_rad, aug.rotate_rad);
    }
    d.augment.insert(d.augment.end(), {static_cast<float>(shift), static_cast<float>(turn)});
  }
  const Pose2 seen = shifted_pose(world_.ego().pose, shift, turn);
  if (augmented) {
    FrameBytes frame(stored_frame_bytes(world_));
    render_stored(world_, frame.data(), &seen);
    record_state(world_, d, frame.data());
  } else {
    record_state(world_, d);
  }
  const Control label = expert_.act(world_);
  Control recorded = label;
  if (augmented) recorded.steer = steer_towards_path(world_, seen);
  record_action(d, recorded, world_.free_lateral());
  return label;  // what the ego executes: the expert's own steer, never the augmented label
}

EpisodeSummary ExpertRecorder::run(int index, uint64_t seed, EpisodeData& d, EpisodeMeta& meta,
                                   const std::string& png_dir, Driver* driver) {
  const CollectSettings& cs = settings_.collect;
  const Task task = collect_task(world_, cs, seed);
  world_.reset(task);
  if (driver) driver->begin_episode(world_, seed);

  begin(d);
  const long expected = static_cast<long>(task.timeout_s / settings_.world.dt) + 1;
  (world_.camera_view() ? d.rgb : d.bev_packed)
      .reserve(stored_frame_bytes(world_) * static_cast<size_t>(expected));

  const NoiseSettings& ns = cs.noise;
  Rng noise_rng(derive_seed(seed, 2));
  double noise_left = 0;
  Control noise_control;
  if (!png_dir.empty()) std::filesystem::create_directories(png_dir);

  Rng augment_rng(derive_seed(seed, 3));
  Rng* augment = settings_.collect.augment.fraction > 0 ? &augment_rng : nullptr;
  const long hold_steps = driver ? 0 : std::lround(cs.hold_s / settings_.world.dt);
  StepResult r;
  while (r.outcome == Outcome::Running) {
    Control label = record_step(d, augment);
    if (observer_) observer_(static_cast<long>(d.frames()) - 1);
    if (!png_dir.empty()) {
      char name[64];
      std::snprintf(name, sizeof name, "/frame_%05zu.png", d.frames() - 1);
      std::vector<uint8_t> planes(d.frame_bytes());
      d.frame_planes(d.frames() - 1, planes.data());
      if (d.camera())  // the BEV's PNGs are drawn larger (write_bev_png's scale)
        write_png_rgb(png_dir + name,
                      frame_picture(planes.data(), d.channels, d.height, d.width, true), d.width,
                      d.height);
      else
        write_bev_png(png_dir + name, planes.data(), d.channels, d.height, d.width);
    }

    Control executed = label;
    if (static_cast<long>(d.frames()) <= hold_steps) {
      executed = Control{0.0, 1.0, label.steer};  // collect.hold_s: held like eval's prefill
    } else if (driver) {
      executed = driver->drive(label);
    } else if (ns.enabled) {
      if (noise_left <= 0 && noise_rng.uniform() < ns.rate_per_s * settings_.world.dt) {
        noise_left = noise_rng.uniform(ns.min_s, ns.max_s);
        bool brake = noise_rng.uniform() < 0.5;
        double level = noise_rng.uniform(0.3, 1.0);
        noise_control = brake ? Control{0.0, level} : Control{level, 0.0};
        // A steering ego also swerves: the expert's steer plus an offset held for the window.
        noise_control.steer = world_.free_lateral() ? noise_rng.uniform(-ns.steer, ns.steer) : 0.0;
      }
      if (noise_left > 0) {
        executed = noise_control;
        if (world_.free_lateral())
          executed.steer = std::clamp(label.steer + noise_control.steer, -1.0, 1.0);
        noise_left -= settings_.world.dt;
      }
    }
    d.noise.push_back(executed.throttle != label.throttle || executed.brake != label.brake ||
                      executed.steer != label.steer);
    r = world_.step(executed);
  }

  meta = recording_meta(world_, settings_);
  meta.suite = "collect-" + settings_.world.traffic;
  meta.seed = seed;
  meta.outcome = outcome_name(r.outcome);
  std::string route;
  for (const auto& e : task.route) route += (route.empty() ? "" : " ") + e;
  char buf[64];
  meta.extra["route"] = route;
  std::snprintf(buf, sizeof buf, "%.3f", task.route_length);
  meta.extra["route_length_m"] = buf;
  std::snprintf(buf, sizeof buf, "%.3f", world_.counters().distance);
  meta.extra["distance_m"] = buf;
  meta.extra["episode_index"] = std::to_string(index);
  meta.extra["red_light_violations"] = std::to_string(world_.counters().red_light_violations);
  if (!r.collided_with.empty()) meta.extra["collided_with"] = r.collided_with;
  meta.extra["noise"] = ns.enabled && !driver ? "on" : "off";
  if (driver) meta.extra["driver"] = driver->describe();

  EpisodeSummary s;
  s.index = index;
  s.outcome = meta.outcome;
  s.frames = static_cast<long>(d.frames());
  s.route_length = task.route_length;
  s.distance = world_.counters().distance;
  s.red_light_violations = world_.counters().red_light_violations;
  s.collided_with = r.collided_with;
  return s;
}

}  // namespace cd
