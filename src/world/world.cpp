#include "world/world.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <unordered_map>

#include <libsumo/libsumo.h>

#include "core/error.hpp"
#include "core/rng.hpp"
#include "world/collision.hpp"
#include "world/sumo_errors.hpp"
#include "world/town.hpp"

namespace cd {

namespace {

// m either side of the route path within which a free-steering ego's front still projects
// onto it (its SUMO stand-in follows that projection).
constexpr double kPathMatchWidth = 4.0;

const std::string kEgo = "ego";
const std::string kEgoType = "cd_ego";
const std::string kEgoRoute = "cd_ego_route";
const std::string kLeader = "leader";  // the leader scenario's car
constexpr double kLeaderLength = 5.0;  // m, SUMO's default vehicle type
constexpr double kRedStartGap = 1.5;
constexpr double kRedWaitAllowance = 60.0;  // s added to a red_light task's timeout   // m from the ego's front to the stop line (red_light)
constexpr double kPedSize = 0.5;        // m, pedestrians are drawn and checked as squares

// A road user's colour on the front camera, from its SUMO id (FNV-1a): one of a few car
// paints, or of a few clothes colours.
uint32_t actor_colour(const std::string& id, bool pedestrian) {
  static const uint32_t cars[] = {0xb0b4b8, 0x202226, 0xe8e8e4, 0x8a1c1c, 0x1c3a6e,
                                  0x2e5a3a, 0x6a6f75, 0xc9a227};
  static const uint32_t clothes[] = {0x3050a0, 0xa03030, 0x303030, 0xd0c060, 0x40804a};
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : id) h = (h ^ c) * 1099511628211ull;
  return pedestrian ? clothes[h % 5] : cars[h % 8];
}

// What a signal head shows for a SUMO link state: 'r', 'y', 'g', or 0 for a light that is off.
char camera_lamp(char sumo_state) {
  switch (sumo_state) {
    case 'r': case 's': return 'r';
    case 'y': case 'u': return 'y';
    case 'G': case 'g': return 'g';
    default: return 0;
  }
}
constexpr double kPathHorizon = 80.0;   // m of route ahead that the checks look at
constexpr double kTopUpPeriod = 1.0;    // s between background refills
bool g_world_alive = false;             // libsumo holds one simulation per process

constexpr double kLaneChangeRoom = 30.0;  // m of an edge's lane needed per lane change on it

// Do the lane changes a drive of `route` from `start_lane` (at start_pos) needs each find
// kLaneChangeRoom metres on their edge?
bool lane_changes_fit(const RoadNetwork& net, const std::vector<std::string>& route,
                      int start_lane, double start_pos) {
  std::unordered_map<std::string, int> per_edge;
  for (const LaneChange& c : net.lane_changes(route, start_lane))
    ++per_edge[net.map.find(c.from)->edge];
  for (const auto& [edge, n] : per_edge) {
    double room = net.rightmost_lane(edge).length - (edge == route.front() ? start_pos : 0.0);
    if (room < kLaneChangeRoom * n) return false;
  }
  return true;
}

// Does the route turn around from one edge to the next (only through U-turn links, SUMO's
// direction t or T)? Networks imported from OSM have such links at dead ends and junctions;
// the built-in towns are built without them.
bool turns_around(const RoadNetwork& net, const std::vector<std::string>& route) {
  for (size_t k = 0; k + 1 < route.size(); ++k) {
    bool turn = false, other = false;
    auto lanes = net.edge_lanes.find(route[k]);
    if (lanes == net.edge_lanes.end()) continue;
    for (const std::string& lane : lanes->second) {
      auto out = net.links.find(lane);
      if (out == net.links.end()) continue;
      for (const Link& l : out->second) {
        const LaneGeom* to = net.map.find(l.to_lane);
        if (!to || to->edge != route[k + 1]) continue;
        (l.direction == 't' || l.direction == 'T' ? turn : other) = true;
      }
    }
    if (turn && !other) return true;
  }
  return false;
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

Vec2 to_vec(const libsumo::TraCIPosition& p) { return {p.x, p.y}; }

// The point `pos` metres along a lane's centre line.
Vec2 point_at(const LaneGeom& lane, double pos) {
  const Polyline& s = lane.shape;
  for (size_t i = 1; i < s.size(); ++i) {
    double len = (s[i] - s[i - 1]).norm();
    if (pos <= len || i + 1 == s.size())
      return s[i - 1] + (s[i] - s[i - 1]) * (len > 1e-9 ? std::min(pos, len) / len : 0.0);
    pos -= len;
  }
  return s.front();
}

}  // namespace

namespace {

std::vector<std::string> sumo_command(const std::string& net_path, double dt, uint64_t seed) {
  char step[32];
  std::snprintf(step, sizeof step, "%.6g", dt);
  return {"sumo",
          "--net-file", net_path,
          "--step-length", step,
          "--seed", std::to_string(seed % 2147483647ull),
          "--no-step-log", "true",
          "--no-warnings", "true",
          "--duration-log.disable", "true",
          "--collision.action", "warn",
          "--collision.mingap-factor", "0",
          "--collision.check-junctions", "true",
          "--ignore-route-errors", "true",
          "--pedestrian.model", "striping",
          // SUMO's drivers gridlock now and then at busy junctions; moving cars that stood 90 s
          // keeps the town flowing (an ego standing that long at the front of a lane may be
          // moved too, which ends its episode as a timeout).
          "--time-to-teleport", "90"};
}

// The network of the simulation just started, read through libsumo.
RoadNetwork read_road_network(const std::string& path) {
  RoadNetwork net;
  net.path = path;
  RoadMap& map_ = net.map;
  static const std::regex crossing_re(".*_c[0-9]+$"), walking_re(".*_w[0-9]+$");
  std::unordered_map<std::string, std::vector<int>> driving_by_edge;
  std::set<std::string> car_edges;
  for (const std::string& id : libsumo::Lane::getIDList()) {
    LaneGeom g;
    g.id = id;
    g.edge = libsumo::Lane::getEdgeID(id);
    g.internal = !id.empty() && id[0] == ':';
    g.width = libsumo::Lane::getWidth(id);
    g.length = libsumo::Lane::getLength(id);
    for (const auto& p : libsumo::Lane::getShape(id).value) g.shape.push_back({p.x, p.y});
    auto us = id.rfind('_');
    g.index = us == std::string::npos ? 0 : std::atoi(id.c_str() + us + 1);
    auto allowed = libsumo::Lane::getAllowed(id);
    auto disallowed = libsumo::Lane::getDisallowed(id);
    bool cars = allowed.empty() ? !contains(disallowed, "passenger") : contains(allowed, "passenger");
    bool peds = allowed.empty() ? !contains(disallowed, "pedestrian") : contains(allowed, "pedestrian");
    if (cars) {
      g.kind = LaneKind::Driving;
      if (!g.internal) {
        car_edges.insert(g.edge);
        net.lane_km += g.length / 1000.0;
      }
    } else if (peds) {
      if (std::regex_match(g.edge, crossing_re) && g.internal) g.kind = LaneKind::Crossing;
      else if (std::regex_match(g.edge, walking_re) && g.internal) g.kind = LaneKind::WalkingArea;
      else g.kind = LaneKind::Sidewalk;
    } else {
      continue;  // rail, bike-only and similar lanes are not part of this world
    }
    if (g.shape.size() < 2) continue;
    map_.add(std::move(g));
    const LaneGeom& added = map_.lanes.back();
    if (added.kind == LaneKind::Sidewalk && !added.internal)
      net.sidewalk_of_edge[added.edge] = map_.lanes.size() - 1;
    if (added.kind == LaneKind::Driving && !added.internal)
      driving_by_edge[added.edge].push_back(static_cast<int>(map_.lanes.size() - 1));
  }
  for (auto& [edge, idx] : driving_by_edge) {
    // The rightmost car lane stands for the edge (insertion positions, lengths).
    int best = idx.front();
    for (int i : idx)
      if (map_.lanes[i].index < map_.lanes[best].index) best = i;
    net.edge_lane[edge] = best;
    for (int i : idx) net.edge_lanes[edge].push_back(map_.lanes[i].id);
  }
  if (car_edges.empty()) throw SimError(path + ": the network has no lane for cars");
  for (auto& [edge, idx] : driving_by_edge) {
    for (int i : idx) {
      LaneGeom& g = map_.lanes[i];
      for (int j : idx) {
        if (map_.lanes[j].index == g.index + 1) g.has_left_neighbour = true;
        if (map_.lanes[j].index == g.index - 1) g.has_right_neighbour = true;
      }
    }
  }
  for (const LaneGeom& g : map_.lanes) {
    if (g.kind != LaneKind::Driving) continue;
    std::vector<Link>& out = net.links[g.id];
    for (const auto& c : libsumo::Lane::getLinks(g.id)) {
      if (!map_.find(c.approachedLane)) continue;
      Link l{c.approachedLane, c.approachedInternal, c.direction.empty() ? 's' : c.direction[0]};
      out.push_back(l);
      if (!g.internal && !c.approachedInternal.empty()) {
        ViaInfo& vi = net.via_info[c.approachedInternal];
        vi.approach = g.id;
        vi.direction = l.direction;
        vi.fixed_state = c.state.empty() ? 'O' : c.state[0];
      }
    }
  }
  // Signalised links read their state from their light's state string at run time.
  for (const std::string& tls : libsumo::TrafficLight::getIDList()) {
    auto controlled = libsumo::TrafficLight::getControlledLinks(tls);
    for (size_t i = 0; i < controlled.size(); ++i)
      for (const auto& link : controlled[i]) {
        auto it = net.via_info.find(link.viaLane);
        if (it != net.via_info.end()) {
          it->second.tls = tls;
          it->second.tls_index = static_cast<int>(i);
        }
      }
  }
  // Every internal lane knows the first internal lane (the via) of its connection.
  for (const auto& [via, info] : net.via_info) {
    std::string lane = via;
    for (int guard = 0; guard < 16 && !lane.empty() && lane[0] == ':'; ++guard) {
      net.via_head[lane] = via;
      auto it = net.links.find(lane);
      if (it == net.links.end() || it->second.empty()) break;
      const Link& l = it->second.front();
      lane = l.via_lane.empty() ? l.to_lane : l.via_lane;
    }
  }
  net.car_edges.assign(car_edges.begin(), car_edges.end());
  for (const auto& [edge, lane] : net.sidewalk_of_edge) net.ped_edges.push_back(edge);
  std::sort(net.ped_edges.begin(), net.ped_edges.end());  // hash order must not decide anything
  // Conflicts inside junctions, for the yielding rule.
  for (const LaneGeom& g : map_.lanes)
    if (g.kind == LaneKind::Driving && g.internal)
      net.internal_foes[g.id] = libsumo::Lane::getInternalFoes(g.id);
  return net;
}


}  // namespace

// What only libsumo knows of this session.
struct World::Sumo {
  // Road users within view_radius after the last step (SUMO's context subscription).
  // Cars report position, angle and speed; persons also their waiting time, which marks them.
  std::map<std::string, std::map<int, std::shared_ptr<libsumo::TraCIResult>>> nearby;
  // A car's length and width, asked once per car and episode: they never change, and leaving
  // them out of the subscription saves two results per car and step.
  std::unordered_map<std::string, std::pair<double, double>> car_sizes;
  std::unordered_map<std::string, std::string> tls_states;  // this step's light states
  long tls_cache_step = -1;
};

bool World::alive() { return g_world_alive; }

World::World(const WorldConfig& config)
    : config_(config), ego_model_(config.ego), sumo_(std::make_unique<Sumo>()) {
  if (g_world_alive)
    throw SimError("only one World per process: libsumo runs a single simulation");
  const std::string net_path = resolve_network(config_.world.town);
  std::vector<std::string> args = sumo_command(net_path, config_.world.dt, 0);
  with_sumo_errors("cannot load network " + net_path,
                   [&] { libsumo::Simulation::start(args); });
  g_world_alive = true;
  try {
    net_ = std::make_shared<const RoadNetwork>(read_road_network(net_path));
    renderer_ = std::make_unique<BevRenderer>(net_->map, config_.bev);
    if (config_.view != "bev" && config_.view != "camera")
      throw ConfigError("sense.view: unknown view '" + config_.view + "' (bev, camera)");
    if (config_.view == "camera")
      camera_ = std::make_unique<CameraRenderer>(net_->map, config_.camera);
    format_ = frame_format_of(config_);
    grid_ = std::make_unique<LaneGrid>(net_->map);
    signal_heads_ = find_signal_heads(*net_);
    free_ = config_.ego.lateral == "free";
  } catch (...) {
    libsumo::Simulation::close();
    g_world_alive = false;
    throw;
  }
}

World::~World() {
  try {
    libsumo::Simulation::close();
  } catch (...) {
  }
  g_world_alive = false;
}

std::vector<std::string> World::sumo_args(uint64_t seed) const {
  return sumo_command(net_->path, config_.world.dt, seed);
}

Task World::sample_task(uint64_t seed, double min_len, double max_len) {
  Rng rng(seed);
  Task best;
  double best_miss = 1e300;
  for (int attempt = 0; attempt < 400; ++attempt) {
    const std::string& from = net_->car_edges[rng.below(net_->car_edges.size())];
    const std::string& to = net_->car_edges[rng.below(net_->car_edges.size())];
    if (from == to) continue;
    libsumo::TraCIStage r = libsumo::Simulation::findRoute(from, to);
    if (r.edges.size() < 2) continue;
    // No U-turns: a free ego's turning circle is too wide for them, and a route-mode ego would
    // be carried round one that no learner sees in town-a's data.
    if (turns_around(*net_, r.edges)) continue;
    double from_len = net_->rightmost_lane(from).length, to_len = net_->rightmost_lane(to).length;
    const double start_pos = std::min(from_len * 0.3, std::max(0.0, from_len - 10.0));
    int start_lane = -1;
    if (free_) {
      // The wheel is the ego's: it starts on the rightmost lane and changes lanes where the
      // route needs it, given room for each change on its edge.
      start_lane = net_->rightmost_lane(from).index;
      if (!lane_changes_fit(*net_, r.edges, start_lane, start_pos)) continue;
    } else {
      // Only routes SUMO can drive for the ego without changing lanes; it starts on the
      // rightmost lane that allows that.
      auto good = net_->lane_plan(r.edges);
      for (const std::string& lane : net_->edge_lanes.at(from)) {
        const LaneGeom* g = net_->map.find(lane);
        if (good.front().count(lane) && (start_lane < 0 || g->index < start_lane) &&
            net_->lane_changes(r.edges, g->index).empty())
          start_lane = g->index;
      }
    }
    if (start_lane < 0) continue;
    Task t;
    t.route = r.edges;
    t.start_lane = start_lane;
    t.start_pos = start_pos;
    t.goal_pos = std::max(1.0, to_len * 0.5);
    // findRoute covers whole edges; the task starts and ends inside them.
    t.route_length = r.length - t.start_pos - (to_len - t.goal_pos);
    t.traffic_seed = rng.next() >> 1;
    double miss = t.route_length < min_len ? min_len - t.route_length
                  : t.route_length > max_len ? t.route_length - max_len : 0.0;
    if (miss < best_miss) {
      best = t;
      best_miss = miss;
    }
    if (miss == 0) break;
  }
  if (best.route.empty()) throw SimError(net_->path + ": no route found between car edges");
  best.timeout_s = best.route_length / (5.0 / 3.6) + 20.0;
  return best;
}

Task World::sample_scenario_task(uint64_t seed, const std::string& scenario, double min_len,
                                 double max_len) {
  Rng rng(seed);
  for (int attempt = 0; attempt < 2000; ++attempt) {
    Task t = sample_task(rng.next() >> 1, min_len, max_len);
    if (t.route_length < min_len || t.route_length > max_len) continue;
    const double first_len = net_->rightmost_lane(t.route.front()).length;
    const double old_start = t.start_pos;
    if (scenario == "route") {
      // the route as sampled
    } else if (scenario == "red_light") {
      const ViaInfo* vi = net_->find_via(net_->first_via(t.route, t.start_lane));
      if (!vi || vi->tls.empty() || first_len < 20) continue;
      t.start_pos = first_len - kRedStartGap;
    } else if (scenario == "leader") {
      t.leader_gap = rng.uniform(3.0, 4.5);
      t.leader_hold_s = rng.uniform(4.0, 8.0);
      // Room for the ego's history behind it and for the leader before the junction.
      const double need = t.leader_gap + kLeaderLength + 15.0;
      if (first_len < need + 10.0) continue;
      t.start_pos = std::min(std::max(10.0, first_len * 0.3), first_len - need);
    } else {
      throw SimError("unknown scenario '" + scenario + "' (known: route, red_light, leader)");
    }
    t.scenario = scenario;
    t.route_length += old_start - t.start_pos;
    if (t.route_length < min_len || t.route_length > max_len) continue;
    t.timeout_s = t.route_length / (5.0 / 3.6) + 20.0;
    // The wait at the red light is part of the task, not of the route: up to a full red
    // phase of netgenerate's programs (under a minute) is added.
    if (scenario == "red_light") t.timeout_s += kRedWaitAllowance;
    return t;
  }
  throw SimError(net_->path + ": no place for a '" + scenario + "' task on this network");
}

void World::wait_for_red_onset() {
  const ViaInfo* vi = net_->find_via(net_->first_via(task_.route, task_.start_lane));
  if (!vi || vi->tls.empty())
    throw SimError("red_light task: the route's first link has no traffic light");
  const int max_steps = static_cast<int>(std::lround(600.0 / config_.world.dt));
  sumo_call("simulation failed while waiting for red", [&] {
    bool was_red = true;  // a red already on at the start is not an onset
    for (int i = 0; i < max_steps; ++i) {
      char st = libsumo::TrafficLight::getRedYellowGreenState(vi->tls).at(vi->tls_index);
      bool red = st == 'r' || st == 'R';
      if (red && !was_red) return;
      was_red = red;
      advance();
    }
    throw SimError("red_light task: the light never turned red in 600 s");
  });
}

void World::reset(const Task& task) {
  if (task.route.empty()) throw SimError("task has an empty route");
  if (std::find(scenario_names().begin(), scenario_names().end(), task.scenario) ==
      scenario_names().end())
    throw SimError("task has an unknown scenario '" + task.scenario + "'");
  if (!free_ && task.start_lane >= 0 && !net_->lane_changes(task.route, task.start_lane).empty())
    throw SimError("the task's route needs a lane change, which only a free-steering ego makes "
                   "(ego.lateral = \"free\")");
  task_ = task;
  if (camera_) camera_->set_weather(episode_weather(config_.camera.weather, task.traffic_seed));
  plan_ = net_->lane_plan(task_.route);
  if (task_.timeout_s <= 0) task_.timeout_s = task_.route_length / (5.0 / 3.6) + 20.0;
  std::vector<std::string> args = sumo_args(task.traffic_seed);
  args.erase(args.begin());  // load() takes the options without the program name
  with_sumo_errors("cannot reload " + net_->path, [&] { libsumo::Simulation::load(args); });
  traffic_rng_ = std::make_unique<Rng>(derive_seed(task.traffic_seed, 1));
  next_actor_id_ = 0;
  sumo_->car_sizes.clear();  // ids start again with the episode
  scripted_ = 0;
  counters_ = {};
  outcome_ = Outcome::Running;
  prev_link_state_ = 0;
  actor_speed_.clear();
  prev_link_distance_ = 1e9;
  ego_present_ = false;
  leader_held_ = false;
  ego_ = {};
  steer_angle_ = 0;
  free_pose_valid_ = false;
  contact_ = {};

  sumo_call("cannot start traffic", [&] {
    libsumo::VehicleType::copy("DEFAULT_VEHTYPE", kEgoType);
    libsumo::VehicleType::setLength(kEgoType, config_.ego.length);
    libsumo::VehicleType::setWidth(kEgoType, config_.ego.width);
    libsumo::VehicleType::setMaxSpeed(kEgoType, config_.ego.max_speed);
    libsumo::VehicleType::setAccel(kEgoType, config_.ego.max_accel);
    libsumo::VehicleType::setDecel(kEgoType, config_.ego.max_decel);
    libsumo::VehicleType::setEmergencyDecel(kEgoType, config_.ego.max_decel);
    libsumo::VehicleType::setImperfection(kEgoType, 0.0);
    libsumo::VehicleType::setColor(kEgoType, libsumo::TraCIColor(255, 40, 40));
    libsumo::Route::add(kEgoRoute, task.route);
    spawn_background();
  });
  int warm_steps = static_cast<int>(std::lround(config_.world.warmup_s / config_.world.dt));
  steps_since_load_ = 0;
  sumo_call("simulation failed during warm-up", [&] {
    for (int i = 0; i < warm_steps; ++i) advance();
  });
  if (task_.scenario == "red_light") wait_for_red_onset();
  insert_ego();
  route_lanes_ = route_lane_sequence();
  renderer_->set_route(route_lanes_);
  refresh();
  ego_.progress = 0;
  if (free_) {
    // From here on the bicycle model drives: it starts where SUMO inserted the ego.
    free_pose_ = ego_.pose;
    free_speed_ = ego_.speed;
    free_pose_valid_ = true;
    contact_ = cd::road_contact(net_->map, *grid_, ego_box());
  }
}

bool World::add_background_car(const std::string& id) {
  Rng& rng = *traffic_rng_;
  const std::string& from = net_->car_edges[rng.below(net_->car_edges.size())];
  const std::string& to = net_->car_edges[rng.below(net_->car_edges.size())];
  if (from == to) return false;
  libsumo::TraCIStage r = libsumo::Simulation::findRoute(from, to);
  if (r.edges.size() < 2) return false;
  const LaneGeom* lane = &net_->rightmost_lane(from);
  double pos = rng.uniform(0.0, std::max(0.0, lane->length - 6.0));
  // Never materialise a car in sight of the ego.
  if (ego_present_ && (point_at(*lane, pos) - ego_.pose.pos).norm() < config_.world.view_radius)
    return false;
  libsumo::Route::add(id + "_r", r.edges);
  char p[32];
  std::snprintf(p, sizeof p, "%.2f", pos);
  libsumo::Vehicle::add(id, id + "_r", "DEFAULT_VEHTYPE", "now", "best", p, "0");
  return true;
}

void World::spawn_background() {
  const TrafficDensity& d = traffic_density(config_.world);
  target_cars_ = static_cast<int>(std::lround(d.cars_per_km * net_->lane_km));
  target_peds_ = net_->ped_edges.empty() ? 0 : static_cast<int>(std::lround(d.peds_per_km * net_->lane_km));
  top_up_background();
}

void World::top_up_background() {
  int cars = static_cast<int>(libsumo::Vehicle::getIDCount()) +
             static_cast<int>(libsumo::Simulation::getPendingVehicles().size());
  if (ego_present_) --cars;
  for (int tries = 0; cars < target_cars_ && tries < 4 * target_cars_; ++tries) {
    if (add_background_car("bg" + std::to_string(next_actor_id_++))) ++cars;
  }
  int peds = libsumo::Person::getIDCount();
  Rng& rng = *traffic_rng_;
  for (int tries = 0; peds < target_peds_ && tries < 4 * target_peds_; ++tries) {
    const std::string& from = net_->ped_edges[rng.below(net_->ped_edges.size())];
    const std::string& to = net_->ped_edges[rng.below(net_->ped_edges.size())];
    if (from == to) continue;
    auto stages = libsumo::Simulation::findIntermodalRoute(from, to, "");
    if (stages.empty() || stages.front().edges.empty()) continue;
    const LaneGeom& walk = net_->map.lanes[net_->sidewalk_of_edge.at(from)];
    const double pos = rng.uniform(0.0, walk.length);
    // Like cars, pedestrians never materialise in sight of the ego.
    if (ego_present_ && (point_at(walk, pos) - ego_.pose.pos).norm() < config_.world.view_radius)
      continue;
    std::string id = "ped" + std::to_string(next_actor_id_++);
    libsumo::Person::add(id, from, pos, libsumo::DEPARTFLAG_NOW);
    for (const auto& st : stages) libsumo::Person::appendStage(id, st);
    ++peds;
  }
}

void World::insert_ego() {
  const std::string& first = task_.route.front();
  const bool leader = task_.scenario == "leader";
  const double clear_ahead = leader ? task_.leader_gap + kLeaderLength + 20 : 20;
  auto clear_start = [&] {
    for (const std::string& v : libsumo::Edge::getLastStepVehicleIDs(first)) {
      double p = libsumo::Vehicle::getLanePosition(v);
      if (v != kEgo && v != kLeader && p > task_.start_pos - 60 && p < task_.start_pos + clear_ahead)
        libsumo::Vehicle::remove(v);
    }
    // Cars still inside the junction before the start (entering the first edge) or on a
    // neighbouring lane's sweep also keep SUMO from inserting there.
    // SUMO inserts the cars of an edge in departure order: a background car waiting to be
    // inserted would hold the ego back behind it.
    for (const std::string& v : libsumo::Simulation::getPendingVehicles())
      if (v != kEgo && v != kLeader) libsumo::Vehicle::remove(v);
    const LaneGeom* g = net_->edge_lane.count(first) ? &net_->rightmost_lane(first) : nullptr;
    if (!g) return;
    const Vec2 at = point_at(*g, std::min(task_.start_pos, g->length));
    for (const std::string& v : libsumo::Vehicle::getIDList()) {
      if (v == kEgo || v == kLeader) continue;
      if ((to_vec(libsumo::Vehicle::getPosition(v)) - at).norm() < 25.0) libsumo::Vehicle::remove(v);
    }
  };
  sumo_call("cannot insert the ego vehicle", [&] {
    clear_start();
    if (leader) {
      // The leader drives the ego's route, held still until leader_hold_s.
      char lp[32];
      std::snprintf(lp, sizeof lp, "%.2f", task_.start_pos + task_.leader_gap + kLeaderLength);
      libsumo::Vehicle::add(kLeader, kEgoRoute, "DEFAULT_VEHTYPE", "now",
                            std::to_string(std::max(0, task_.start_lane)), lp, "0");
      libsumo::Vehicle::setSpeed(kLeader, 0);
      leader_held_ = true;
    }
    char p[32];
    std::snprintf(p, sizeof p, "%.2f", task_.start_pos);
    const std::string lane = task_.start_lane >= 0 ? std::to_string(task_.start_lane) : "best";
    libsumo::Vehicle::add(kEgo, kEgoRoute, kEgoType, "now", lane, p, "0", "current", "max");
    // SUMO's own strategic lane changes would move a free ego's stand-in before it is ours.
    if (free_) libsumo::Vehicle::setLaneChangeMode(kEgo, 0);
    for (int i = 0; i < 50; ++i) {
      advance();
      if (contains(libsumo::Vehicle::getIDList(), kEgo) &&
          (!leader || contains(libsumo::Vehicle::getIDList(), kLeader))) {
        libsumo::Vehicle::setSpeedMode(kEgo, 0);
        libsumo::Vehicle::setLaneChangeMode(kEgo, 0);
        libsumo::Vehicle::setSpeed(kEgo, 0);
        const double r = config_.world.view_radius;
        libsumo::Vehicle::subscribeContext(
            kEgo, libsumo::CMD_GET_VEHICLE_VARIABLE, r,
            {libsumo::VAR_POSITION, libsumo::VAR_ANGLE, libsumo::VAR_SPEED});
        libsumo::Vehicle::subscribeContext(
            kEgo, libsumo::CMD_GET_PERSON_VARIABLE, r,
            {libsumo::VAR_POSITION, libsumo::VAR_ANGLE, libsumo::VAR_SPEED,
             libsumo::VAR_WAITING_TIME});
        advance();  // subscription results exist after a step
        sumo_->nearby = libsumo::Vehicle::getContextSubscriptionResults(kEgo);
        ego_entry_time_ = libsumo::Simulation::getTime();
        ego_present_ = true;
        return;
      }
      clear_start();
    }
    throw SimError("the start position stayed blocked");
  });
}

std::vector<std::string> World::route_lane_sequence() const {
  std::vector<std::string> lanes;
  std::string lane = libsumo::Vehicle::getLaneID(kEgo);
  size_t k = 0;
  while (!lane.empty() && lanes.size() < 10000) {
    lanes.push_back(lane);
    lane = net_->lane_after(task_.route, plan_, lane, k);
  }
  return lanes;
}

StepResult World::step(const Control& c) {
  if (outcome_ != Outcome::Running) throw SimError("step() after the episode ended; call reset()");
  double v0 = ego_.speed;
  double v1 = ego_model_.next_speed(c, v0, config_.world.dt);
  bool present = true;
  if (leader_held_ && ego_.time >= task_.leader_hold_s) {
    leader_held_ = false;
    // SUMO's driver takes over (it may have left already: then there is nothing to do).
    sumo_call("cannot release the leader", [&] {
      if (contains(libsumo::Vehicle::getIDList(), kLeader)) libsumo::Vehicle::setSpeed(kLeader, -1);
    });
  }
  if (free_) {
    steer_angle_ = ego_model_.next_steer_angle(steer_angle_, c.steer, config_.world.dt);
    free_pose_ = ego_model_.next_pose(free_pose_, v0, v1, steer_angle_, config_.world.dt);
    free_speed_ = v1;
  }
  double sumo_speed = v1;
  if (free_) {
    // SUMO's ego stays on its route's lanes, where SUMO's drivers see it, and is moved to where
    // the bicycle's front bumper projects onto the route path this step. (Placing it with
    // moveToXY crashed SUMO 1.15 inside junctions.) Off the path it keeps the bicycle's speed.
    const double h = free_pose_.heading;
    const Vec2 front = free_pose_.pos + Vec2{std::cos(h), std::sin(h)} * (0.5 * config_.ego.length);
    double s = 0;
    if (follow_lane_change(front))
      sumo_speed = v1;
    else if (path_.locate(front, kPathMatchWidth, &s))
      sumo_speed = std::clamp(s / config_.world.dt, 0.0, config_.ego.max_speed);
  }
  sumo_call("simulation step failed", [&] {
    libsumo::Vehicle::setSpeed(kEgo, sumo_speed);
    advance();
    // The ego is part of its own context subscription: absent from it means gone.
    sumo_->nearby = libsumo::Vehicle::getContextSubscriptionResults(kEgo);
    // SUMO teleports a car that stood --time-to-teleport seconds; the ego may come back
    // further along within the same step, so the teleport itself ends its episode.
    present = sumo_->nearby.count(kEgo) > 0 &&
              !contains(libsumo::Simulation::getStartingTeleportIDList(), kEgo);
  });
  StepResult r;
  sumo_call("reading the simulation failed", [&] { r = check_events(present); });
  outcome_ = r.outcome;
  return r;
}

bool World::follow_lane_change(Vec2 front) {
  const LaneGeom* on = net_->map.find(ego_.lane);
  if (!on || on->internal) return false;
  auto it = net_->edge_lanes.find(on->edge);
  if (it == net_->edge_lanes.end()) return false;
  const LaneGeom* best = nullptr;
  double best_lat = 1e300;
  for (const std::string& id : it->second) {
    const LaneGeom* g = net_->map.find(id);
    const LaneProjection p = project_on_lane(*g, free_pose_.pos);
    if (p.on && std::abs(p.lateral) < best_lat) {
      best = g;
      best_lat = std::abs(p.lateral);
    }
  }
  if (!best || best == on) return false;
  // Its front where the bicycle's front projects on the new lane, less this step's travel
  // (the step's setSpeed moves it on).
  const double along = project_on_lane(*best, front).along - free_speed_ * config_.world.dt;
  const double pos = std::clamp(along, std::min(config_.ego.length, best->length), best->length);
  sumo_call("cannot move the ego to lane " + best->id,
            [&] { libsumo::Vehicle::moveTo(kEgo, best->id, pos); });
  ++counters_.lane_changes;
  return true;
}

bool World::lane_change_clear(const LaneGeom& to, double pos) const {
  for (const Actor& a : actors_) {
    if (a.pedestrian) continue;
    const LaneProjection p = project_on_lane(to, a.box.center);
    if (!p.on) continue;
    // Room ahead of the ego's front for it, and behind its rear for the car to brake.
    const double d = p.along - pos;  // + ahead of the ego's front
    const double behind = config_.ego.length + 3.0 + 1.5 * a.speed + 0.5 * a.box.length;
    if (d > -behind && d < 6.0 + 0.5 * a.box.length) return false;
  }
  return true;
}

void World::hand_ego_to_sumo() {
  const double r = config_.world.view_radius;
  sumo_call("cannot hand the ego to SUMO", [r] {
    libsumo::Vehicle::setSpeedMode(kEgo, 31);
    libsumo::Vehicle::setSpeed(kEgo, -1);
    // The baseline is SUMO alone: the World's own queries are not part of it.
    libsumo::Vehicle::unsubscribeContext(kEgo, libsumo::CMD_GET_VEHICLE_VARIABLE, r);
    libsumo::Vehicle::unsubscribeContext(kEgo, libsumo::CMD_GET_PERSON_VARIABLE, r);
  });
}

void World::step_bare() {
  sumo_call("simulation step failed", [&] { advance(); });
}

void World::advance() {
  libsumo::Simulation::step();
  ++steps_since_load_;
  int period = std::max(1, static_cast<int>(std::lround(kTopUpPeriod / config_.world.dt)));
  if (steps_since_load_ % period == 0) top_up_background();
}

StepResult World::check_events(bool present) {
  StepResult r;
  // A free-steering ego's SUMO stand-in rides the lane centre: only our own test (below, on the
  // bicycle's footprint) decides its collisions.
  for (const auto& col : libsumo::Simulation::getCollisions()) {
    if (free_) break;
    if (col.collider == kEgo || col.victim == kEgo) {
      r.outcome = Outcome::Collision;
      r.collided_with = col.collider == kEgo ? col.victim : col.collider;
      r.ego_struck = col.collider == kEgo;  // SUMO names the striker the collider
      r.collision_kind = "vehicle";
      for (const Actor& a : actors_)
        if (a.id == r.collided_with && a.pedestrian) r.collision_kind = "pedestrian";
      break;
    }
  }
  if (!present) {
    // SUMO teleports a vehicle stuck for --time-to-teleport: for the ego that is a timeout.
    if (r.outcome != Outcome::Collision) r.outcome = Outcome::Timeout;
    return r;
  }
  // The light the ego was heading for before this step: refresh() moves on to the next one.
  const std::string prev_lane = ego_.lane;
  const double prev_progress = ego_.progress;
  const char crossed_state = prev_link_state_;
  const double crossed_distance = prev_link_distance_;
  refresh();
  counters_.distance += std::max(0.0, ego_.progress - prev_progress);

  if (r.outcome != Outcome::Collision) {
    const Box eb = ego_box();
    for (const Actor& a : actors_) {
      if (boxes_overlap(eb, a.box)) {
        r.outcome = Outcome::Collision;
        r.collided_with = a.id;
        r.collision_kind = a.pedestrian ? "pedestrian" : "vehicle";
        r.ego_struck = a_strikes(eb, ego_.speed, a.box, a.speed);
        break;
      }
    }
  }
  if (free_) {
    const bool was_wrong = contact_.wrong_way, was_invading = contact_.lane_invasion;
    contact_ = cd::road_contact(net_->map, *grid_, ego_box());
    r.wrong_way = contact_.wrong_way && !was_wrong;
    r.lane_invasion = contact_.lane_invasion && !was_invading;
    counters_.wrong_way += r.wrong_way;
    counters_.lane_invasions += r.lane_invasion;
    if (contact_.lane >= 0) {
      counters_.lateral_error_sum += std::abs(contact_.lateral_error);
      ++counters_.lateral_samples;
    }
    if (r.outcome == Outcome::Running && contact_.offroad) r.outcome = Outcome::Offroad;
  }
  r.entered_light = light_at_junction_entry(prev_lane, ego_.lane, crossed_state, crossed_distance);
  if (r.entered_light == kTlRed) {
    r.ran_red_light = true;
    ++counters_.red_light_violations;
  }
  if (r.outcome == Outcome::Running) {
    const LaneGeom* g = net_->map.find(ego_.lane);
    if (g && !g->internal && g->edge == task_.route.back() && ego_.lane_pos >= task_.goal_pos)
      r.outcome = Outcome::Success;
    else if (ego_.time >= task_.timeout_s)
      r.outcome = Outcome::Timeout;
  }
  return r;
}

void World::refresh() {
  const double t = libsumo::Simulation::getTime();
  Vec2 front = to_vec(libsumo::Vehicle::getPosition(kEgo));
  double angle = libsumo::Vehicle::getAngle(kEgo);
  Box eb = box_from_front(front, angle, config_.ego.length, config_.ego.width);
  double new_speed = free_pose_valid_ ? free_speed_ : libsumo::Vehicle::getSpeed(kEgo);
  ego_.accel = (new_speed - ego_.speed) / config_.world.dt;
  ego_.speed = new_speed;
  ego_.pose = free_pose_valid_ ? free_pose_ : Pose2{eb.center, eb.heading};
  ego_.lane = libsumo::Vehicle::getLaneID(kEgo);
  ego_.lane_pos = libsumo::Vehicle::getLanePosition(kEgo);
  ego_.lane_speed_limit = libsumo::Lane::getMaxSpeed(ego_.lane);
  ego_.progress = libsumo::Vehicle::getDistance(kEgo);
  ego_.time = t - ego_entry_time_;

  // Nearby road users come from a context subscription around the ego: SUMO finds them
  // through its spatial index, where asking for every actor by id would cost far more.
  actors_.clear();
  const double r2 = config_.world.view_radius * config_.world.view_radius;
  for (const auto& [id, vars] : sumo_->nearby) {
    if (id == kEgo) continue;
    auto number = [&](int var) {
      auto it = vars.find(var);
      return it == vars.end() ? 0.0 : static_cast<const libsumo::TraCIDouble&>(*it->second).value;
    };
    auto pit = vars.find(libsumo::VAR_POSITION);
    if (pit == vars.end()) continue;
    const auto& pos = static_cast<const libsumo::TraCIPosition&>(*pit->second);
    Vec2 p{pos.x, pos.y};
    Vec2 d = p - front;
    if (d.dot(d) > r2) continue;
    Actor a;
    a.id = id;
    a.pedestrian = vars.count(libsumo::VAR_WAITING_TIME) > 0;  // only persons report it
    // A position is the front of a car or person; persons are squares of kPedSize.
    if (a.pedestrian) {
      a.box = box_from_front(p, number(libsumo::VAR_ANGLE), kPedSize, kPedSize);
    } else {
      auto size = sumo_->car_sizes.find(id);
      if (size == sumo_->car_sizes.end())
        size = sumo_->car_sizes
                   .emplace(id, std::pair{libsumo::Vehicle::getLength(id),
                                          libsumo::Vehicle::getWidth(id)})
                   .first;
      a.box = box_from_front(p, number(libsumo::VAR_ANGLE), size->second.first,
                             size->second.second);
    }
    a.speed = number(libsumo::VAR_SPEED);
    auto prev = actor_speed_.find(id);
    a.accel = prev == actor_speed_.end() ? 0.0 : (a.speed - prev->second) / config_.world.dt;
    actors_.push_back(std::move(a));
  }
  actor_speed_.clear();
  for (const Actor& a : actors_) actor_speed_[a.id] = a.speed;
  LaneChangeOptions changes;
  changes.clear = [this](const LaneGeom& to, double pos) { return lane_change_clear(to, pos); };
  path_ = trace_route_path(*net_, task_.route, plan_, ego_.lane, ego_.lane_pos, kPathHorizon,
                           changes);
  const TruthStep ts = compute_ground_truth(
      {*net_, path_, actors_, ego_.pose, ego_.speed, config_.ego.width, config_.world,
       [this](const ViaInfo& vi) { return link_state(vi); },
       [this](const std::string& lane, bool minor) { return junction_lane_blocked(lane, minor); },
       config_.ego.length});
  truth_ = ts.truth;
  command_ = ts.command;
  prev_link_state_ = ts.next_light_state;
  prev_link_distance_ = ts.next_light_distance;
}

char World::link_state(const ViaInfo& vi) const {
  if (vi.tls.empty()) return vi.fixed_state;
  if (sumo_->tls_cache_step != steps_since_load_) {
    sumo_->tls_states.clear();
    sumo_->tls_cache_step = steps_since_load_;
  }
  auto it = sumo_->tls_states.find(vi.tls);
  if (it == sumo_->tls_states.end())
    it = sumo_->tls_states.emplace(vi.tls, libsumo::TrafficLight::getRedYellowGreenState(vi.tls)).first;
  const std::string& st = it->second;
  return vi.tls_index >= 0 && vi.tls_index < static_cast<int>(st.size()) ? st[vi.tls_index] : 'O';
}

bool World::junction_lane_blocked(const std::string& lane, bool minor) {
  const WorldSettings& xs = config_.world;
  for (const std::string& foe : net_->foes_of(lane)) {
    const LaneGeom* fg = net_->map.find(foe);
    if (!fg) continue;
    if (fg->kind == LaneKind::Crossing) {
      // Pedestrians on the crossing, or walking towards it from the corner.
      for (const Actor& a : actors_) {
        if (!a.pedestrian) continue;
        std::string road = libsumo::Person::getRoadID(a.id);
        if (road == fg->edge) return true;
        if (!road.empty() && road[0] == ':' && a.speed > 0.2 &&
            libsumo::Person::getNextEdge(a.id) == fg->edge)
          return true;
      }
      continue;
    }
    if (fg->kind != LaneKind::Driving) continue;
    for (const std::string& v : libsumo::Lane::getLastStepVehicleIDs(foe)) {
      // A car waiting inside the junction yields to a prioritised ego.
      if (v != kEgo && (minor || libsumo::Vehicle::getSpeed(v) > 1.0)) return true;
    }
    if (!minor) continue;
    // Priority traffic about to enter the foe lane.
    const ViaInfo* fvi = net_->find_via(net_->via_of(foe));
    if (!fvi) continue;
    const char foe_state = link_state(*fvi);
    if (is_minor_link(foe_state)) continue;
    const LaneGeom* ag = net_->map.find(fvi->approach);
    if (!ag) continue;
    for (const std::string& v : libsumo::Lane::getLastStepVehicleIDs(fvi->approach)) {
      if (v == kEgo) continue;
      // Stopped cars do not count: they wait for something else, and SUMO's drivers brake
      // for a car already inside the junction when they start.
      double dist = ag->length - libsumo::Vehicle::getLanePosition(v);
      double sp = libsumo::Vehicle::getSpeed(v);
      if (sp > 0.5 && dist / sp < xs.yield_time) return true;
    }
  }
  return false;
}

BevScene World::scene() const {
  BevScene sc;
  sc.ego = ego_.pose;
  for (const Actor& a : actors_) (a.pedestrian ? sc.pedestrians : sc.vehicles).push_back(a.box);
  if (truth_.tl_state != kTlNone) {
    // The stop line lies tl_distance ahead along the path, across the lane.
    if (const auto line = path_.line_across(truth_.tl_distance)) {
      const BevChannel ch = truth_.tl_state == kTlGreen        ? kBevLightGreen
                            : truth_.tl_state == kTlGreenYield ? kBevLightYield
                                                               : kBevLightRed;
      sc.stop_lines.push_back({line->first, line->second, ch});
    }
  }
  return sc;
}

std::vector<SignalHead> find_signal_heads(const RoadNetwork& net) {
  std::map<std::string, std::vector<std::pair<std::string, const ViaInfo*>>> by_approach;
  for (const auto& [via, info] : net.via_info)
    if (!info.tls.empty()) by_approach[info.approach].emplace_back(via, &info);
  std::vector<SignalHead> heads;
  for (auto& [approach, vias] : by_approach) {
    const LaneGeom* lane = net.map.find(approach);
    if (!lane) continue;
    const Polyline pts = without_repeats(lane->shape);
    if (pts.size() < 2) continue;
    std::sort(vias.begin(), vias.end());
    const ViaInfo* shown = vias.front().second;
    for (const auto& [via, info] : vias)
      if (info->direction == 's') {
        shown = info;
        break;
      }
    const Vec2 end = pts.back(), d = end - pts[pts.size() - 2];
    const Vec2 dir = d * (1.0 / d.norm()), right{dir.y, -dir.x};
    heads.push_back({approach, end + right * (0.5 * lane->width + 0.6),
                     std::atan2(-dir.y, -dir.x), shown});
  }
  return heads;
}

CameraScene World::camera_scene(double radius) const {
  CameraScene sc;
  sc.ego = ego_.pose;
  for (const Actor& a : actors_) {
    if (a.pedestrian) {
      CameraScene::Pedestrian p;
      p.box = a.box;
      p.colour = actor_colour(a.id, true);
      sc.pedestrians.push_back(p);
    } else {
      CameraScene::Vehicle v;
      v.box = a.box;
      v.colour = actor_colour(a.id, false);
      v.braking = a.accel < -1.0;
      sc.vehicles.push_back(v);
    }
  }
  const double r2 = radius * radius;
  for (const SignalHead& h : signal_heads_) {
    const Vec2 d = h.pole - ego_.pose.pos;
    if (d.dot(d) > r2) continue;
    char state = link_state(*h.via);
    if (h.approach == ego_.lane && truth_.tl_state != kTlNone)
      state = truth_.tl_state == kTlRed ? 'r' : truth_.tl_state == kTlYellow ? 'y' : 'G';
    const char head = camera_lamp(state);
    if (head != 0) sc.lights.push_back({h.pole, h.facing, head});
  }
  return sc;
}

void World::render(uint8_t* out) const {
  if (camera_)
    camera_->render(camera_scene(), out);
  else
    renderer_->render(scene(), out);
}

void World::render_from(const Pose2& seen, uint8_t* out) const {
  if (camera_) {
    CameraScene sc = camera_scene();
    sc.ego = seen;
    camera_->render(sc, out);
  } else {
    BevScene sc = scene();
    sc.ego = seen;
    renderer_->render(sc, out);
  }
}

void World::render_packed(uint8_t* out) const {
  if (camera_) throw std::logic_error("render_packed: the camera's frames are RGB, not bit planes");
  renderer_->render_packed(scene(), out);
}

std::string World::add_scripted_vehicle(const std::string& lane_id, double pos, double speed) {
  const LaneGeom* g = net_->map.find(lane_id);
  if (!g) throw SimError("unknown lane " + lane_id);
  std::string id = "scripted" + std::to_string(scripted_++);
  sumo_call("cannot add scripted vehicle", [&] {
    libsumo::Route::add(id + "_r", {g->edge});
    char p[32], v[32];
    std::snprintf(p, sizeof p, "%.3f", pos);
    std::snprintf(v, sizeof v, "%.3f", speed);
    libsumo::Vehicle::add(id, id + "_r", "DEFAULT_VEHTYPE", "now", std::to_string(g->index), p, v);
    libsumo::Vehicle::setSpeedMode(id, 0);
    libsumo::Vehicle::setLaneChangeMode(id, 0);
    libsumo::Vehicle::setSpeed(id, speed);
  });
  return id;
}

std::string World::add_scripted_pedestrian(const std::string& edge, double pos) {
  std::string id = "scripted_ped" + std::to_string(scripted_++);
  sumo_call("cannot add scripted pedestrian", [&] {
    libsumo::Person::add(id, edge, pos, libsumo::DEPARTFLAG_NOW);
    libsumo::Person::appendWaitingStage(id, 1e6);
  });
  return id;
}

void World::place_pedestrian(const std::string& id, Vec2 at) {
  sumo_call("cannot place pedestrian " + id, [&] {
    // keepRoute 2: exactly there, off the pedestrian network if need be.
    libsumo::Person::moveToXY(id, "", at.x, at.y, libsumo::INVALID_DOUBLE_VALUE, 2);
  });
}

void World::set_vehicle_speed(const std::string& id, double speed) {
  sumo_call("cannot set speed of " + id, [&] { libsumo::Vehicle::setSpeed(id, speed); });
}

}  // namespace cd
