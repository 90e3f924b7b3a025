#include "world/world.hpp"

#include <algorithm>
#include <cmath>
#include <regex>
#include <set>

#include <libsumo/libsumo.h>

#include "core/error.hpp"
#include "core/rng.hpp"
#include "world/collision.hpp"
#include "world/sumo_errors.hpp"
#include "world/town.hpp"

namespace cd {

namespace {

const std::string kEgo = "ego";
const std::string kEgoType = "cd_ego";
const std::string kEgoRoute = "cd_ego_route";
const std::string kLeader = "leader";  // the leader scenario's car
constexpr double kLeaderLength = 5.0;  // m, SUMO's default vehicle type
constexpr double kRedStartGap = 1.5;
constexpr double kRedWaitAllowance = 60.0;  // s added to a red_light task's timeout   // m from the ego's front to the stop line (red_light)
constexpr double kPedSize = 0.5;        // m, pedestrians are drawn and checked as squares
constexpr double kPathHorizon = 80.0;   // m of route ahead that the checks look at
constexpr double kTopUpPeriod = 1.0;    // s between background refills
bool g_world_alive = false;             // libsumo holds one simulation per process

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

bool is_upper(char c) { return c >= 'A' && c <= 'Z'; }

int tl_code(char state) {
  switch (state) {
    case 'r': case 'R': case 'u': case 's': return kTlRed;
    case 'y': case 'Y': return kTlYellow;
    case 'G': return kTlGreen;
    case 'g': return kTlGreenYield;
    default: return kTlNone;
  }
}

int command_of(char direction) {
  switch (direction) {
    case 'l': case 'L': case 't': return kLeft;
    case 'r': case 'R': return kRight;
    case 's': return kStraight;
    default: return kFollow;
  }
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

const char* outcome_name(Outcome o) {
  switch (o) {
    case Outcome::Running: return "running";
    case Outcome::Success: return "success";
    case Outcome::Collision: return "collision";
    case Outcome::Timeout: return "timeout";
  }
  return "?";
}

World::World(const Settings& settings) : settings_(settings), ego_model_(settings.ego) {
  if (g_world_alive)
    throw SimError("only one World per process: libsumo runs a single simulation");
  net_path_ = resolve_network(settings_.world.town);
  std::vector<std::string> args = sumo_args(0);
  with_sumo_errors("cannot load network " + net_path_,
                   [&] { libsumo::Simulation::start(args); });
  g_world_alive = true;
  try {
    build_map();
    renderer_ = std::make_unique<BevRenderer>(map_, settings_.bev);
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
  char step[32];
  std::snprintf(step, sizeof step, "%.6g", settings_.world.dt);
  return {"sumo",
          "--net-file", net_path_,
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

void World::build_map() {
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
        lane_km_ += g.length / 1000.0;
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
      sidewalk_of_edge_[added.edge] = map_.lanes.size() - 1;
    if (added.kind == LaneKind::Driving && !added.internal)
      driving_by_edge[added.edge].push_back(static_cast<int>(map_.lanes.size() - 1));
  }
  for (auto& [edge, idx] : driving_by_edge) {
    // The rightmost car lane stands for the edge (insertion positions, lengths).
    int best = idx.front();
    for (int i : idx)
      if (map_.lanes[i].index < map_.lanes[best].index) best = i;
    edge_lane_[edge] = &map_.lanes[best];
    for (int i : idx) edge_lanes_[edge].push_back(map_.lanes[i].id);
  }
  if (car_edges.empty()) throw SimError(net_path_ + ": the network has no lane for cars");
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
    std::vector<Link>& out = links_[g.id];
    for (const auto& c : libsumo::Lane::getLinks(g.id)) {
      if (!map_.find(c.approachedLane)) continue;
      Link l{c.approachedLane, c.approachedInternal, c.direction.empty() ? 's' : c.direction[0]};
      out.push_back(l);
      if (!g.internal && !c.approachedInternal.empty()) {
        ViaInfo& vi = via_info_[c.approachedInternal];
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
        auto it = via_info_.find(link.viaLane);
        if (it != via_info_.end()) {
          it->second.tls = tls;
          it->second.tls_index = static_cast<int>(i);
        }
      }
  }
  // Every internal lane knows the first internal lane (the via) of its connection.
  for (const auto& [via, info] : via_info_) {
    std::string lane = via;
    for (int guard = 0; guard < 16 && !lane.empty() && lane[0] == ':'; ++guard) {
      via_head_[lane] = via;
      auto it = links_.find(lane);
      if (it == links_.end() || it->second.empty()) break;
      const Link& l = it->second.front();
      lane = l.via_lane.empty() ? l.to_lane : l.via_lane;
    }
  }
  car_edges_.assign(car_edges.begin(), car_edges.end());
  for (const auto& [edge, lane] : sidewalk_of_edge_) ped_edges_.push_back(edge);
  std::sort(ped_edges_.begin(), ped_edges_.end());  // hash order must not decide anything
}

std::string World::next_lane(const std::string& lane, const std::string& to_edge,
                             const std::unordered_set<std::string>* good) const {
  auto it = links_.find(lane);
  if (it == links_.end()) return "";
  std::string fallback;
  for (const Link& l : it->second) {
    const LaneGeom* to = map_.find(l.to_lane);
    if (!to || to->edge != to_edge) continue;
    std::string next = l.via_lane.empty() ? l.to_lane : l.via_lane;
    if (!good || good->count(l.to_lane)) return next;
    if (fallback.empty()) fallback = next;
  }
  return fallback;
}

std::vector<std::unordered_set<std::string>> World::lane_plan(
    const std::vector<std::string>& route) const {
  // good[k]: lanes of route edge k from which the rest of the route is drivable without a
  // lane change (the ego never changes lanes), computed from the goal backwards.
  std::vector<std::unordered_set<std::string>> good(route.size());
  for (size_t k = route.size(); k-- > 0;) {
    auto it = edge_lanes_.find(route[k]);
    if (it == edge_lanes_.end()) break;
    for (const std::string& lane : it->second) {
      if (k + 1 == route.size()) {
        good[k].insert(lane);
        continue;
      }
      auto lit = links_.find(lane);
      if (lit == links_.end()) continue;
      for (const Link& l : lit->second)
        if (good[k + 1].count(l.to_lane)) good[k].insert(lane);
    }
  }
  return good;
}

Task World::sample_task(uint64_t seed, double min_len, double max_len) {
  Rng rng(seed);
  Task best;
  double best_miss = 1e300;
  for (int attempt = 0; attempt < 400; ++attempt) {
    const std::string& from = car_edges_[rng.below(car_edges_.size())];
    const std::string& to = car_edges_[rng.below(car_edges_.size())];
    if (from == to) continue;
    libsumo::TraCIStage r = libsumo::Simulation::findRoute(from, to);
    if (r.edges.size() < 2) continue;
    double from_len = edge_lane_.at(from)->length, to_len = edge_lane_.at(to)->length;
    // Only routes the ego can drive without changing lanes; it starts on the rightmost lane
    // that allows that.
    auto good = lane_plan(r.edges);
    int start_lane = -1;
    for (const std::string& lane : edge_lanes_.at(from)) {
      const LaneGeom* g = map_.find(lane);
      if (good.front().count(lane) && (start_lane < 0 || g->index < start_lane))
        start_lane = g->index;
    }
    if (start_lane < 0) continue;
    Task t;
    t.route = r.edges;
    t.start_lane = start_lane;
    t.start_pos = std::min(from_len * 0.3, std::max(0.0, from_len - 10.0));
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
  if (best.route.empty()) throw SimError(net_path_ + ": no route found between car edges");
  best.timeout_s = best.route_length / (5.0 / 3.6) + 20.0;
  return best;
}

const std::vector<std::string>& scenario_names() {
  static const std::vector<std::string> names = {"route", "red_light", "leader"};
  return names;
}

std::string World::first_via(const Task& task) const {
  if (task.route.size() < 2 || task.start_lane < 0) return "";
  auto plan = lane_plan(task.route);
  const std::string lane = task.route[0] + "_" + std::to_string(task.start_lane);
  return next_lane(lane, task.route[1], &plan[1]);
}

Task World::sample_scenario_task(uint64_t seed, const std::string& scenario, double min_len,
                                 double max_len) {
  Rng rng(seed);
  for (int attempt = 0; attempt < 2000; ++attempt) {
    Task t = sample_task(rng.next() >> 1, min_len, max_len);
    if (t.route_length < min_len || t.route_length > max_len) continue;
    const double first_len = edge_lane_.at(t.route.front())->length;
    const double old_start = t.start_pos;
    if (scenario == "route") {
      // the route as sampled
    } else if (scenario == "red_light") {
      const ViaInfo* vi = via_info(first_via(t));
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
  throw SimError(net_path_ + ": no place for a '" + scenario + "' task on this network");
}

void World::wait_for_red_onset() {
  const ViaInfo* vi = via_info(first_via(task_));
  if (!vi || vi->tls.empty())
    throw SimError("red_light task: the route's first link has no traffic light");
  const int max_steps = static_cast<int>(std::lround(600.0 / settings_.world.dt));
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
  task_ = task;
  plan_ = lane_plan(task_.route);
  if (task_.timeout_s <= 0) task_.timeout_s = task_.route_length / (5.0 / 3.6) + 20.0;
  std::vector<std::string> args = sumo_args(task.traffic_seed);
  args.erase(args.begin());  // load() takes the options without the program name
  with_sumo_errors("cannot reload " + net_path_, [&] { libsumo::Simulation::load(args); });
  traffic_rng_ = std::make_unique<Rng>(derive_seed(task.traffic_seed, 1));
  next_actor_id_ = 0;
  scripted_ = 0;
  counters_ = {};
  outcome_ = Outcome::Running;
  prev_link_state_ = 0;
  prev_link_distance_ = 1e9;
  ego_present_ = false;
  leader_held_ = false;
  ego_ = {};

  sumo_call("cannot start traffic", [&] {
    libsumo::VehicleType::copy("DEFAULT_VEHTYPE", kEgoType);
    libsumo::VehicleType::setLength(kEgoType, settings_.ego.length);
    libsumo::VehicleType::setWidth(kEgoType, settings_.ego.width);
    libsumo::VehicleType::setMaxSpeed(kEgoType, settings_.ego.max_speed);
    libsumo::VehicleType::setAccel(kEgoType, settings_.ego.max_accel);
    libsumo::VehicleType::setDecel(kEgoType, settings_.ego.max_decel);
    libsumo::VehicleType::setEmergencyDecel(kEgoType, settings_.ego.max_decel);
    libsumo::VehicleType::setImperfection(kEgoType, 0.0);
    libsumo::VehicleType::setColor(kEgoType, libsumo::TraCIColor(255, 40, 40));
    libsumo::Route::add(kEgoRoute, task.route);
    spawn_background();
  });
  int warm_steps = static_cast<int>(std::lround(settings_.world.warmup_s / settings_.world.dt));
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
}

bool World::add_background_car(const std::string& id) {
  Rng& rng = *traffic_rng_;
  const std::string& from = car_edges_[rng.below(car_edges_.size())];
  const std::string& to = car_edges_[rng.below(car_edges_.size())];
  if (from == to) return false;
  libsumo::TraCIStage r = libsumo::Simulation::findRoute(from, to);
  if (r.edges.size() < 2) return false;
  const LaneGeom* lane = edge_lane_.at(from);
  double pos = rng.uniform(0.0, std::max(0.0, lane->length - 6.0));
  // Never materialise a car in sight of the ego.
  if (ego_present_ && (point_at(*lane, pos) - ego_.pose.pos).norm() < settings_.world.view_radius)
    return false;
  libsumo::Route::add(id + "_r", r.edges);
  char p[32];
  std::snprintf(p, sizeof p, "%.2f", pos);
  libsumo::Vehicle::add(id, id + "_r", "DEFAULT_VEHTYPE", "now", "best", p, "0");
  return true;
}

void World::spawn_background() {
  const TrafficDensity& d = traffic_density(settings_.world);
  target_cars_ = static_cast<int>(std::lround(d.cars_per_km * lane_km_));
  target_peds_ = ped_edges_.empty() ? 0 : static_cast<int>(std::lround(d.peds_per_km * lane_km_));
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
    const std::string& from = ped_edges_[rng.below(ped_edges_.size())];
    const std::string& to = ped_edges_[rng.below(ped_edges_.size())];
    if (from == to) continue;
    auto stages = libsumo::Simulation::findIntermodalRoute(from, to, "");
    if (stages.empty() || stages.front().edges.empty()) continue;
    const LaneGeom& walk = map_.lanes[sidewalk_of_edge_.at(from)];
    const double pos = rng.uniform(0.0, walk.length);
    // Like cars, pedestrians never materialise in sight of the ego.
    if (ego_present_ && (point_at(walk, pos) - ego_.pose.pos).norm() < settings_.world.view_radius)
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
    const LaneGeom* g = edge_lane_.count(first) ? edge_lane_.at(first) : nullptr;
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
    for (int i = 0; i < 50; ++i) {
      advance();
      if (contains(libsumo::Vehicle::getIDList(), kEgo) &&
          (!leader || contains(libsumo::Vehicle::getIDList(), kLeader))) {
        libsumo::Vehicle::setSpeedMode(kEgo, 0);
        libsumo::Vehicle::setLaneChangeMode(kEgo, 0);
        libsumo::Vehicle::setSpeed(kEgo, 0);
        const double r = settings_.world.view_radius;
        libsumo::Vehicle::subscribeContext(
            kEgo, libsumo::CMD_GET_VEHICLE_VARIABLE, r,
            {libsumo::VAR_POSITION, libsumo::VAR_ANGLE, libsumo::VAR_SPEED, libsumo::VAR_LENGTH,
             libsumo::VAR_WIDTH});
        libsumo::Vehicle::subscribeContext(
            kEgo, libsumo::CMD_GET_PERSON_VARIABLE, r,
            {libsumo::VAR_POSITION, libsumo::VAR_ANGLE, libsumo::VAR_SPEED});
        advance();  // subscription results exist after a step
        nearby_ = libsumo::Vehicle::getContextSubscriptionResults(kEgo);
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
    lane = lane_after(lane, k);
  }
  return lanes;
}

std::string World::lane_after(const std::string& lane, size_t& k) const {
  const LaneGeom* g = map_.find(lane);
  if (!g) return "";
  if (g->internal) {
    auto it = links_.find(lane);
    if (it == links_.end() || it->second.empty()) return "";
    const Link& l = it->second.front();
    return l.via_lane.empty() ? l.to_lane : l.via_lane;
  }
  while (k < task_.route.size() && task_.route[k] != g->edge) ++k;
  if (k + 1 >= task_.route.size()) return "";
  return next_lane(lane, task_.route[k + 1], k + 1 < plan_.size() ? &plan_[k + 1] : nullptr);
}

StepResult World::step(const Control& c) {
  if (outcome_ != Outcome::Running) throw SimError("step() after the episode ended; call reset()");
  double v0 = ego_.speed;
  double v1 = ego_model_.next_speed(c, v0, settings_.world.dt);
  bool present = true;
  if (leader_held_ && ego_.time >= task_.leader_hold_s) {
    leader_held_ = false;
    // SUMO's driver takes over (it may have left already: then there is nothing to do).
    sumo_call("cannot release the leader", [&] {
      if (contains(libsumo::Vehicle::getIDList(), kLeader)) libsumo::Vehicle::setSpeed(kLeader, -1);
    });
  }
  sumo_call("simulation step failed", [&] {
    libsumo::Vehicle::setSpeed(kEgo, v1);
    advance();
    // The ego is part of its own context subscription: absent from it means gone.
    nearby_ = libsumo::Vehicle::getContextSubscriptionResults(kEgo);
    // SUMO teleports a car that stood --time-to-teleport seconds; the ego may come back
    // further along within the same step, so the teleport itself ends its episode.
    present = nearby_.count(kEgo) > 0 &&
              !contains(libsumo::Simulation::getStartingTeleportIDList(), kEgo);
  });
  StepResult r;
  sumo_call("reading the simulation failed", [&] { r = check_events(present); });
  outcome_ = r.outcome;
  return r;
}

void World::hand_ego_to_sumo() {
  const double r = settings_.world.view_radius;
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
  int period = std::max(1, static_cast<int>(std::lround(kTopUpPeriod / settings_.world.dt)));
  if (steps_since_load_ % period == 0) top_up_background();
}

StepResult World::check_events(bool present) {
  StepResult r;
  for (const auto& col : libsumo::Simulation::getCollisions()) {
    if (col.collider == kEgo || col.victim == kEgo) {
      r.outcome = Outcome::Collision;
      r.collided_with = col.collider == kEgo ? col.victim : col.collider;
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
    Box ego_box{ego_.pose.pos, ego_.pose.heading, settings_.ego.length, settings_.ego.width};
    for (const Actor& a : actors_) {
      if (boxes_overlap(ego_box, a.box)) {
        r.outcome = Outcome::Collision;
        r.collided_with = a.id;
        break;
      }
    }
  }
  bool now_internal = !ego_.lane.empty() && ego_.lane[0] == ':';
  bool was_internal = !prev_lane.empty() && prev_lane[0] == ':';
  if (now_internal && !was_internal && tl_code(crossed_state) == kTlRed &&
      crossed_distance < 10.0) {
    r.ran_red_light = true;
    ++counters_.red_light_violations;
  }
  if (r.outcome == Outcome::Running) {
    const LaneGeom* g = map_.find(ego_.lane);
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
  Box eb = box_from_front(front, angle, settings_.ego.length, settings_.ego.width);
  double new_speed = libsumo::Vehicle::getSpeed(kEgo);
  ego_.accel = (new_speed - ego_.speed) / settings_.world.dt;
  ego_.speed = new_speed;
  ego_.pose = {eb.center, eb.heading};
  ego_.lane = libsumo::Vehicle::getLaneID(kEgo);
  ego_.lane_pos = libsumo::Vehicle::getLanePosition(kEgo);
  ego_.lane_speed_limit = libsumo::Lane::getMaxSpeed(ego_.lane);
  ego_.progress = libsumo::Vehicle::getDistance(kEgo);
  ego_.time = t - ego_entry_time_;

  // Nearby road users come from a context subscription around the ego: SUMO finds them
  // through its spatial index, where asking for every actor by id would cost far more.
  actors_.clear();
  const double r2 = settings_.world.view_radius * settings_.world.view_radius;
  for (const auto& [id, vars] : nearby_) {
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
    a.pedestrian = vars.find(libsumo::VAR_LENGTH) == vars.end();  // only cars report sizes
    // A position is the front of a car or person; persons are squares of kPedSize.
    a.box = a.pedestrian
                ? box_from_front(p, number(libsumo::VAR_ANGLE), kPedSize, kPedSize)
                : box_from_front(p, number(libsumo::VAR_ANGLE), number(libsumo::VAR_LENGTH),
                                 number(libsumo::VAR_WIDTH));
    a.speed = number(libsumo::VAR_SPEED);
    actors_.push_back(std::move(a));
  }
  compute_path();
  compute_truth();
}

void World::compute_path() {
  path_.clear();
  std::string lane = ego_.lane;
  double from = ego_.lane_pos, s = 0;
  size_t k = 0;
  while (!lane.empty() && s < kPathHorizon) {
    const LaneGeom* g = map_.find(lane);
    if (!g) break;
    path_.push_back({g, from, s});
    if (!g->internal && g->edge == task_.route.back()) break;  // the goal lies on this lane
    s += std::max(0.0, g->length - from);
    from = 0;
    lane = lane_after(lane, k);
  }
  path_min_ = {1e300, 1e300};
  path_max_ = {-1e300, -1e300};
  for (const PathLane& pl : path_)
    for (const Vec2& q : pl.lane->shape) {
      path_min_ = {std::min(path_min_.x, q.x), std::min(path_min_.y, q.y)};
      path_max_ = {std::max(path_max_.x, q.x), std::max(path_max_.y, q.y)};
    }
}

Vec2 World::path_point(double s) const {
  Vec2 last = ego_.pose.pos;
  for (const PathLane& pl : path_) {
    const Polyline& shape = pl.lane->shape;
    double arc = 0;
    for (size_t i = 1; i < shape.size(); ++i) {
      Vec2 a = shape[i - 1], d = shape[i] - a;
      double len = d.norm();
      if (len < 1e-9) continue;
      double lo = std::max(arc, pl.from_pos), hi = arc + len;
      if (hi > lo) {
        double s_lo = pl.s_begin + lo - pl.from_pos, s_hi = pl.s_begin + hi - pl.from_pos;
        if (s <= s_hi) return a + d * ((std::max(s, s_lo) - pl.s_begin + pl.from_pos - arc) / len);
        last = shape[i];
      }
      arc = hi;
    }
  }
  return last;
}

bool World::on_path(Vec2 p, double half_width, double* s_out) const {
  if (p.x < path_min_.x - half_width || p.x > path_max_.x + half_width ||
      p.y < path_min_.y - half_width || p.y > path_max_.y + half_width)
    return false;
  double best = 1e300;
  for (const PathLane& pl : path_) {
    const Polyline& shape = pl.lane->shape;
    double arc = 0;
    for (size_t i = 1; i < shape.size(); ++i) {
      Vec2 a = shape[i - 1], d = shape[i] - a;
      double len = d.norm();
      if (len < 1e-9) continue;
      Vec2 u = d * (1.0 / len);
      double along = (p - a).dot(u);
      double lat = std::abs((p - a).cross(u));
      if (along >= -0.5 && along <= len + 0.5 && lat <= half_width) {
        double lane_pos = arc + std::clamp(along, 0.0, len);
        if (lane_pos >= pl.from_pos - 0.01) best = std::min(best, pl.s_begin + lane_pos - pl.from_pos);
      }
      arc += len;
    }
    if (best < 1e300) break;  // later lanes are farther along the path
  }
  if (best >= 1e300) return false;
  *s_out = best;
  return true;
}

void World::compute_truth() {
  GroundTruth gt;
  const ExpertSettings& xs = settings_.expert;
  // What the ego's own body would sweep along the path, plus a margin.
  const double half_body = settings_.ego.width / 2;

  for (const Actor& a : actors_) {
    double s_min = 1e300;
    double hw = half_body + (a.pedestrian ? xs.ped_margin : xs.vehicle_margin);
    // Nothing of this actor can be near the path: skip the per-segment tests.
    const double reach = hw + (a.box.length + a.box.width) / 2 + a.speed * xs.ped_lookahead_s;
    if (a.box.center.x < path_min_.x - reach || a.box.center.x > path_max_.x + reach ||
        a.box.center.y < path_min_.y - reach || a.box.center.y > path_max_.y + reach)
      continue;
    auto corners = box_corners(a.box);
    auto test = [&](Vec2 p) {
      double s;
      if (on_path(p, hw, &s)) s_min = std::min(s_min, s);
    };
    test(a.box.center);
    if (a.pedestrian) {
      Vec2 dir{std::cos(a.box.heading), std::sin(a.box.heading)};
      test(a.box.center + dir * (a.speed * xs.ped_lookahead_s));
    } else {
      for (const Vec2& c : corners) test(c);
    }
    if (s_min >= 1e300) continue;
    // Distance from the ego's front: a vehicle overlapping it laterally counts from 0.
    if (a.pedestrian) {
      if (!gt.ped_on_path || s_min < gt.ped_distance) {
        gt.ped_on_path = true;
        gt.ped_distance = s_min;
      }
    } else if (!gt.lead_present || s_min < gt.lead_distance) {
      gt.lead_present = true;
      gt.lead_distance = s_min;
      double rel = a.box.heading - ego_.pose.heading;
      gt.lead_speed = a.speed * std::cos(rel);
    }
  }

  // The first signalised link on the path ahead.
  prev_link_state_ = 0;
  prev_link_distance_ = 1e9;
  for (const PathLane& pl : path_) {
    if (pl.s_begin <= 0 || !pl.lane->internal) continue;
    const ViaInfo* vi = via_info(pl.lane->id);
    if (!vi || vi->tls.empty()) continue;
    char state = link_state(*vi);
    gt.tl_state = tl_code(state);
    gt.tl_distance = pl.s_begin;
    prev_link_state_ = state;
    prev_link_distance_ = pl.s_begin;
    break;
  }

  // The next junction on the path (or the one the ego is in): its internal lanes, the
  // approach lane before them, and the state and direction of the ego's link.
  size_t j0 = path_.size();
  for (size_t i = 0; i < path_.size(); ++i)
    if (path_[i].lane->internal) {
      j0 = i;
      break;
    }
  command_ = kFollow;
  gt.junction_distance = j0 < path_.size() ? path_[j0].s_begin : 0.0;
  gt.junction_exit_distance = 0;
  if (j0 < path_.size()) {
    size_t j1 = j0;
    while (j1 < path_.size() && path_[j1].lane->internal) ++j1;
    gt.junction_exit_distance =
        j1 < path_.size() ? path_[j1].s_begin
                          : path_[j1 - 1].s_begin + path_[j1 - 1].lane->length - path_[j1 - 1].from_pos;
    const bool inside = j0 == 0;
    const ViaInfo* vi = via_info(via_head(path_[j0].lane->id));
    const char dir = vi ? vi->direction : 's';
    const char state = vi ? link_state(*vi) : 'O';
    if (inside || gt.junction_distance <= settings_.world.command_horizon) command_ = command_of(dir);
    // The ego decides at the junction's entry for all of its internal lanes; once inside it
    // is committed (waiting in the middle would leave it standing in other cars' paths).
    const bool minor = !is_upper(state) || state == 'O';
    for (size_t j = j0; !inside && j < j1 && !gt.must_yield; ++j) {
      if (junction_lane_blocked(path_[j].lane->id, minor)) {
        gt.must_yield = true;
        gt.yield_distance = gt.junction_distance;
      }
    }
  }

  double v = ego_.speed;
  gt.path_free_distance = v * v / (2 * xs.comfort_decel) + settings_.world.path_free_margin;
  const double d = gt.path_free_distance;
  gt.path_free = !(gt.lead_present && gt.lead_distance < d) &&
                 !((gt.tl_state == kTlRed || gt.tl_state == kTlYellow) && gt.tl_distance < d) &&
                 !(gt.ped_on_path && gt.ped_distance < d) &&
                 !(gt.must_yield && gt.yield_distance < d);
  truth_ = gt;
}

const World::ViaInfo* World::via_info(const std::string& via) const {
  auto it = via_info_.find(via);
  return it == via_info_.end() ? nullptr : &it->second;
}

char World::link_state(const ViaInfo& vi) {
  if (vi.tls.empty()) return vi.fixed_state;
  if (tls_cache_step_ != steps_since_load_) {
    tls_states_.clear();
    tls_cache_step_ = steps_since_load_;
  }
  auto it = tls_states_.find(vi.tls);
  if (it == tls_states_.end())
    it = tls_states_.emplace(vi.tls, libsumo::TrafficLight::getRedYellowGreenState(vi.tls)).first;
  const std::string& st = it->second;
  return vi.tls_index >= 0 && vi.tls_index < static_cast<int>(st.size()) ? st[vi.tls_index] : 'O';
}

const std::string& World::via_head(const std::string& internal_lane) const {
  auto it = via_head_.find(internal_lane);
  return it == via_head_.end() ? internal_lane : it->second;
}

const std::vector<std::string>& World::internal_foes(const std::string& lane) {
  auto it = foes_.find(lane);
  if (it == foes_.end()) it = foes_.emplace(lane, libsumo::Lane::getInternalFoes(lane)).first;
  return it->second;
}

bool World::junction_lane_blocked(const std::string& lane, bool minor) {
  const ExpertSettings& xs = settings_.expert;
  for (const std::string& foe : internal_foes(lane)) {
    const LaneGeom* fg = map_.find(foe);
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
    const ViaInfo* fvi = via_info(via_head(foe));
    if (!fvi) continue;
    const char foe_state = link_state(*fvi);
    if (!is_upper(foe_state) || foe_state == 'O') continue;
    const LaneGeom* ag = map_.find(fvi->approach);
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
    double s = truth_.tl_distance;
    for (const PathLane& pl : path_) {
      double end = pl.s_begin + pl.lane->length - pl.from_pos;
      if (s > end + 1e-6) continue;
      const Polyline& shape = pl.lane->shape;
      double target = pl.from_pos + (s - pl.s_begin), arc = 0;
      for (size_t i = 1; i < shape.size(); ++i) {
        Vec2 dv = shape[i] - shape[i - 1];
        double len = dv.norm();
        if (len < 1e-9) continue;
        if (arc + len >= target - 1e-6 || i + 1 == shape.size()) {
          Vec2 u = dv * (1.0 / len);
          Vec2 p = shape[i - 1] + u * std::clamp(target - arc, 0.0, len);
          Vec2 n{-u.y, u.x};
          double hw = pl.lane->width / 2;
          BevChannel ch = truth_.tl_state == kTlGreen        ? kBevLightGreen
                          : truth_.tl_state == kTlGreenYield ? kBevLightYield
                                                             : kBevLightRed;
          sc.stop_lines.push_back({p + n * hw, p - n * hw, ch});
          break;
        }
        arc += len;
      }
      break;
    }
  }
  return sc;
}

void World::render(uint8_t* out) const { renderer_->render(scene(), out); }

void World::render_packed(uint8_t* out) const { renderer_->render_packed(scene(), out); }

std::string World::add_scripted_vehicle(const std::string& lane_id, double pos, double speed) {
  const LaneGeom* g = map_.find(lane_id);
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

void World::set_vehicle_speed(const std::string& id, double speed) {
  sumo_call("cannot set speed of " + id, [&] { libsumo::Vehicle::setSpeed(id, speed); });
}

}  // namespace cd
