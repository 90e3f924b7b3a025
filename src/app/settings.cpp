#include "app/settings.hpp"

#include <limits>

#include <nlohmann/json.hpp>

#include "core/config.hpp"
#include "core/error.hpp"

namespace cd {

namespace {

void read_density(const Section& s, TrafficDensity& d) {
  d.cars_per_km = s.number("cars_per_km", d.cars_per_km, 0, 200);
  d.peds_per_km = s.number("peds_per_km", d.peds_per_km, 0, 200);
  s.finish();
}

}  // namespace

Settings load_settings(const std::string& path) {
  Section root = ConfigFile::load(path);
  Settings st;
  st.source = path;

  Section w = root.section("world");
  st.world.town = w.string("town", st.world.town);
  st.world.traffic = w.string("traffic", st.world.traffic, {"empty", "regular", "dense"});
  st.world.dt = w.number("dt", st.world.dt, 0.01, 1.0);
  st.world.warmup_s = w.number("warmup_s", st.world.warmup_s, 0, 3600);
  Section dens = w.section("density");
  read_density(dens.section("regular"), st.world.regular);
  read_density(dens.section("dense"), st.world.dense);
  dens.finish();
  st.world.view_radius = w.number("view_radius", st.world.view_radius, 10, 500);
  st.world.command_horizon = w.number("command_horizon", st.world.command_horizon, 0, 500);
  st.world.path_free_margin = w.number("path_free_margin", st.world.path_free_margin, 0, 100);
  w.finish();

  Section e = root.section("ego");
  st.ego.length = e.number("length", st.ego.length, 1, 20);
  st.ego.width = e.number("width", st.ego.width, 0.5, 5);
  st.ego.max_accel = e.number("max_accel", st.ego.max_accel, 0.1, 20);
  st.ego.max_decel = e.number("max_decel", st.ego.max_decel, 0.1, 20);
  st.ego.max_speed = e.number("max_speed", st.ego.max_speed, 1, 80);
  st.ego.rolling = e.number("rolling", st.ego.rolling, 0, 2);
  st.ego.drag = e.number("drag", st.ego.drag, 0, 0.1);
  e.finish();

  Section b = root.section("bev");
  st.bev.height = static_cast<int>(b.integer("height", st.bev.height, 8, 1024));
  st.bev.width = static_cast<int>(b.integer("width", st.bev.width, 8, 1024));
  st.bev.metres_per_pixel = b.number("metres_per_pixel", st.bev.metres_per_pixel, 0.05, 5);
  st.bev.ego_row_fraction = b.number("ego_row_fraction", st.bev.ego_row_fraction, 0.0, 1.0);
  st.bev.dash_length = b.number("dash_length", st.bev.dash_length, 0.1, 50);
  st.bev.dash_gap = b.number("dash_gap", st.bev.dash_gap, 0.1, 50);
  st.bev.marking_width = b.number("marking_width", st.bev.marking_width, 0.01, 2);
  st.bev.static_supersample =
      static_cast<int>(b.integer("static_supersample", st.bev.static_supersample, 1, 8));
  b.finish();

  Section x = root.section("expert");
  st.expert.cruise_speed = x.number("cruise_speed", st.expert.cruise_speed, 0.5, 40);
  st.expert.turn_speed = x.number("turn_speed", st.expert.turn_speed, 0.5, 40);
  st.expert.comfort_decel = x.number("comfort_decel", st.expert.comfort_decel, 0.5, 10);
  st.expert.min_gap = x.number("min_gap", st.expert.min_gap, 0.5, 20);
  st.expert.headway = x.number("headway", st.expert.headway, 0.1, 5);
  st.expert.stop_margin = x.number("stop_margin", st.expert.stop_margin, 0, 10);
  st.expert.yield_time = x.number("yield_time", st.expert.yield_time, 0, 30);
  st.expert.vehicle_margin = x.number("vehicle_margin", st.expert.vehicle_margin, 0, 5);
  st.expert.ped_margin = x.number("ped_margin", st.expert.ped_margin, 0, 5);
  st.expert.ped_lookahead_s = x.number("ped_lookahead_s", st.expert.ped_lookahead_s, 0, 10);
  st.expert.gain = x.number("gain", st.expert.gain, 0.1, 20);
  x.finish();

  Section c = root.section("collect");
  st.collect.episodes = static_cast<int>(c.integer("episodes", st.collect.episodes, 1, 1000000));
  st.collect.seed = static_cast<uint64_t>(
      c.integer("seed", static_cast<int64_t>(st.collect.seed), 0,
                std::numeric_limits<int64_t>::max()));
  st.collect.workers = static_cast<int>(c.integer("workers", st.collect.workers, 1, 256));
  st.collect.out = c.string("out", st.collect.out);
  st.collect.min_route_m = c.number("min_route_m", st.collect.min_route_m, 0, 1e5);
  st.collect.max_route_m = c.number("max_route_m", st.collect.max_route_m, 1, 1e5);
  st.collect.max_episode_s = c.number("max_episode_s", st.collect.max_episode_s, 0, 1e5);
  Section n = c.section("noise");
  st.collect.noise.enabled = n.boolean("enabled", st.collect.noise.enabled);
  st.collect.noise.rate_per_s = n.number("rate_per_s", st.collect.noise.rate_per_s, 0, 10);
  st.collect.noise.min_s = n.number("min_s", st.collect.noise.min_s, 0.1, 60);
  st.collect.noise.max_s = n.number("max_s", st.collect.noise.max_s, 0.1, 60);
  n.finish();
  c.finish();
  if (st.collect.max_route_m < st.collect.min_route_m)
    throw ConfigError(path + ": collect.max_route_m must be >= collect.min_route_m");
  if (st.collect.noise.max_s < st.collect.noise.min_s)
    throw ConfigError(path + ": collect.noise.max_s must be >= collect.noise.min_s");

  root.finish();
  return st;
}

const TrafficDensity& traffic_density(const WorldSettings& w) {
  static const TrafficDensity none{};
  if (w.traffic == "regular") return w.regular;
  if (w.traffic == "dense") return w.dense;
  return none;
}

nlohmann::json settings_to_json(const Settings& s) {
  using nlohmann::json;
  json j;
  j["world"] = {{"town", s.world.town},
                {"traffic", s.world.traffic},
                {"dt", s.world.dt},
                {"warmup_s", s.world.warmup_s},
                {"density",
                 {{"regular", {{"cars_per_km", s.world.regular.cars_per_km},
                               {"peds_per_km", s.world.regular.peds_per_km}}},
                  {"dense", {{"cars_per_km", s.world.dense.cars_per_km},
                             {"peds_per_km", s.world.dense.peds_per_km}}}}},
                {"view_radius", s.world.view_radius},
                {"command_horizon", s.world.command_horizon},
                {"path_free_margin", s.world.path_free_margin}};
  j["ego"] = {{"length", s.ego.length},       {"width", s.ego.width},
              {"max_accel", s.ego.max_accel}, {"max_decel", s.ego.max_decel},
              {"max_speed", s.ego.max_speed}, {"rolling", s.ego.rolling},
              {"drag", s.ego.drag}};
  j["bev"] = {{"height", s.bev.height},
              {"width", s.bev.width},
              {"metres_per_pixel", s.bev.metres_per_pixel},
              {"ego_row_fraction", s.bev.ego_row_fraction},
              {"dash_length", s.bev.dash_length},
              {"dash_gap", s.bev.dash_gap},
              {"marking_width", s.bev.marking_width},
              {"static_supersample", s.bev.static_supersample}};
  j["expert"] = {{"cruise_speed", s.expert.cruise_speed},
                 {"turn_speed", s.expert.turn_speed},
                 {"comfort_decel", s.expert.comfort_decel},
                 {"min_gap", s.expert.min_gap},
                 {"headway", s.expert.headway},
                 {"stop_margin", s.expert.stop_margin},
                 {"yield_time", s.expert.yield_time},
                 {"vehicle_margin", s.expert.vehicle_margin},
                 {"ped_margin", s.expert.ped_margin},
                 {"ped_lookahead_s", s.expert.ped_lookahead_s},
                 {"gain", s.expert.gain}};
  j["collect"] = {{"episodes", s.collect.episodes},
                  {"seed", s.collect.seed},
                  {"workers", s.collect.workers},
                  {"out", s.collect.out},
                  {"min_route_m", s.collect.min_route_m},
                  {"max_route_m", s.collect.max_route_m},
                  {"max_episode_s", s.collect.max_episode_s},
                  {"noise",
                   {{"enabled", s.collect.noise.enabled},
                    {"rate_per_s", s.collect.noise.rate_per_s},
                    {"min_s", s.collect.noise.min_s},
                    {"max_s", s.collect.noise.max_s}}}};
  return j;
}

}  // namespace cd
