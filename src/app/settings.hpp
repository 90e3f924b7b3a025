#pragma once
// Every setting of a run, read from a TOML config (configs/quickstart.toml shows them all with
// their defaults). Unknown keys and out-of-range values are errors naming file and key.
#include <cstdint>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "sense/bev.hpp"

namespace cd {

struct TrafficDensity {
  double cars_per_km = 0;  // background cars per km of driving lane
  double peds_per_km = 0;  // pedestrians per km of driving lane
};

struct WorldSettings {
  std::string town = "town-a";  // a town name (towns/*.toml) or a path to a .net.xml
  std::string traffic = "regular";  // empty | regular | dense
  double dt = 0.1;                  // s per step
  double warmup_s = 60;             // background traffic runs this long before the ego enters
  TrafficDensity regular{4.0, 3.0};
  TrafficDensity dense{9.0, 8.0};
  double view_radius = 60;      // m, actors farther than this are not sensed or checked
  double command_horizon = 30;  // m, the junction command is given this far ahead
  double path_free_margin = 6;  // m checked beyond the stopping distance for "path free"
};

// Longitudinal vehicle model of the ego: a = throttle * max_accel * (1 - v / max_speed)
// - brake * max_decel - rolling - drag * v^2, speed clamped to [0, max_speed].
struct EgoSettings {
  double length = 4.5;
  double width = 1.8;
  double max_accel = 3.5;   // m/s^2 at standstill, full throttle
  double max_decel = 8.0;   // m/s^2, full brake
  double max_speed = 20.0;  // m/s
  double rolling = 0.1;     // m/s^2, when moving
  double drag = 0.0008;     // 1/m
};

struct ExpertSettings {
  double cruise_speed = 10.0;   // m/s, never above the lane's limit
  double turn_speed = 5.0;      // m/s through turns
  double comfort_decel = 3.0;   // m/s^2, planned braking
  double min_gap = 3.5;         // m, standstill gap to the leader
  double headway = 1.2;         // s
  double stop_margin = 1.0;     // m before a stop line
  double yield_time = 5.0;      // s, priority traffic closer than this in time is waited for
  double vehicle_margin = 0.4;  // m beside the ego's body within which a car is in the way
  double ped_margin = 0.8;      // m beside the ego's body within which a pedestrian is
  double ped_lookahead_s = 1.5; // s, pedestrians are also checked where they will be
  double gain = 2.0;            // 1/s, speed tracking gain
};

struct NoiseSettings {
  bool enabled = false;
  double rate_per_s = 0.05;  // expected starts of a noise window per second
  double min_s = 0.5;        // window length range
  double max_s = 1.5;
};

struct CollectSettings {
  int episodes = 24;
  uint64_t seed = 0;
  int workers = 2;
  std::string out = "runs/quickstart/data";
  double min_route_m = 300;
  double max_route_m = 700;
  double max_episode_s = 0;  // 0: the benchmark timeout (route at 5 km/h + 20 s)
  NoiseSettings noise;
};

// Speed controller of every agent with a target-speed output (control/pid.hpp).
struct ControlSettings {
  double kp = 4.0;              // 1/s: m/s^2 asked per m/s of speed error
  double ki = 0.5;              // 1/s^2
  double kd = 0.0;              // dimensionless
  double integral_limit = 2.0;  // m, anti-windup bound of the integrated error
  double stop_speed = 0.1;      // m/s: a target and a speed both below it mean "hold still"
  double hold_brake = 0.3;      // brake held while standing
};

// The network of the behaviour-cloning methods (bc-so, bc-oh) and what it sees.
struct ModelSettings {
  std::string backbone = "small";  // small (CPU-sized CNN) | resnet34 (the seeds', GPU)
  int history = 4;                 // frames stacked by bc-oh (bc-so: 1)
  int history_stride = 2;          // simulation steps between stacked frames
  std::string action_head = "throttle_brake";  // throttle_brake | target_speed
  bool speed_input = false;        // false: the measured speed is zeroed (the seeds' POMDP)
  int features = 256;              // width of the backbone's output and the branches
  double speed_loss_weight = 0.05; // auxiliary speed-prediction head
  double dropout = 0.2;
};

struct TrainSettings {
  int epochs = 8;
  int batch_size = 64;
  double lr = 2e-4;
  std::string loss = "l1";       // l1 | l2
  double val_fraction = 0.1;     // of the episodes, held out for validation
  int lr_patience = 1;           // epochs without a better validation loss before a decay
  double lr_decay = 0.5;
  double lr_min = 1e-6;
  uint64_t seed = 0;
  int threads = 2;               // torch intra-op threads
  std::string device = "cpu";    // cpu | cuda | auto
  long max_samples = 0;          // 0: every sample of the data folder
  std::string out = "runs/quickstart/train";
};

struct EvalSettings {
  std::string suite = "quickstart";  // a built-in suite name or a suite file
  int trials = 0;                    // 0: the suite's own number of trials
  int workers = 2;
  std::string out = "runs/quickstart/eval";
  double prefill_s = 1.0;   // s the ego is held still while the agent's history fills
  double cs_speed = 8.0;    // m/s of the constant-speed baseline
  int max_attempts = 3;     // an episode whose worker or SUMO crashed is run again this often
};

// Perception model of the cim family (seed 000 section 5.4.2): a beta-VAE on one grey BEV view.
struct VaeSettings {
  std::string view = "vehicles";  // BEV channel(s) merged into the grey input, "a+b" for several
  int latents = 128;
  double beta = 6.0;     // cim and cim-mlp; cim-entangled trains with beta = 1
  int epochs = 4;
  int batch_size = 64;
  double lr = 1e-3;
  long max_frames = 30000;  // seeded subset of the data's frames it trains on, 0 = all
};

// Cause selection and the causal speed predictor (seed 000 sections 4.2, 5.4.3).
struct CimSettings {
  int lags = 3;                         // Granger lags
  double alpha = 0.01;                  // level of the Granger tests
  std::string correction = "bonferroni";  // none | bonferroni | bh
  int max_causes = 4;                   // at most this many selected (smallest p, then F); 0 = all
  int series_stride = 5;                // simulation steps between the samples of the series
  int history = 3;                      // last values of each variable the predictor sees
  int history_stride = 1;               // simulation steps between them
  int encoder_units = 16;               // per-variable linear encoder of cim, cim-entangled
  int mlp_encoder_units = 8;            // per-variable encoder of cim-mlp (all latents)
  int hidden = 64;                      // width of the predictor MLP
  int epochs = 50;                      // speed predictor epochs
  int batch_size = 256;
  double lr = 1e-3;
};

// The imitative trajectory model (dim) and its ensemble (rip), seed 000 section 5.3.
struct DimSettings {
  int horizon = 4;          // future waypoints predicted
  int waypoint_step = 5;    // simulation steps between waypoints (0.5 s at dt 0.1)
  int past = 4;             // past ego positions it is conditioned on
  int features = 128;       // width of the BEV encoder output
  int hidden = 128;
  double min_std = 0.05;    // m, lower bound of each step's standard deviation
  int plan_iterations = 10; // gradient-ascent steps of the planner
  int replan_steps = 2;     // the agent plans every this many simulation steps
  double plan_lr = 0.2;     // m per step (Adam)
  double goal_distance = 20;  // m along the route: the goal the plan is pulled toward
  double goal_weight = 0.02;  // weight of -|last waypoint - goal|^2 (per m^2) in the objective
  int ensemble = 3;           // rip: DIMs trained on bootstrap resamples of the episodes
  std::string aggregation = "worst";  // rip: worst (min over members) | mean
};

struct Settings {
  std::string source = "(built-in defaults)";  // where they came from
  WorldSettings world;
  EgoSettings ego;
  BevConfig bev;
  ExpertSettings expert;
  CollectSettings collect;
  ControlSettings control;
  ModelSettings model;
  TrainSettings train;
  EvalSettings eval;
  VaeSettings vae;
  CimSettings cim;
  DimSettings dim;
};

Settings load_settings(const std::string& path);  // throws ConfigError
nlohmann::json settings_to_json(const Settings& s);
const TrafficDensity& traffic_density(const WorldSettings& w);

}  // namespace cd
