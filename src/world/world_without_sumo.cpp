// The World of a build without SUMO (CMakeLists.txt: -DCD_WITH_SUMO=OFF): constructing one is
// the one-line MissingPart error of core/build_parts.hpp. No World exists in such a build, so the
// other members are never reached; they are defined for the linker.
#include "core/build_parts.hpp"
#include "core/rng.hpp"
#include "world/world.hpp"

namespace cd {

struct World::Sumo {};

namespace {

[[noreturn]] void no_world() { require_sumo("the driving world"); throw MissingPart("no SUMO"); }

}  // namespace

World::World(const WorldConfig& config) : config_(config), ego_model_(config.ego) { no_world(); }
bool World::alive() { return false; }
World::~World() = default;
Task World::sample_task(uint64_t, double, double) { no_world(); }
Task World::sample_scenario_task(uint64_t, const std::string&, double, double) { no_world(); }
void World::reset(const Task&) { no_world(); }
StepResult World::step(const Control&) { no_world(); }
void World::hand_ego_to_sumo() { no_world(); }
void World::step_bare() { no_world(); }
void World::render(uint8_t*) const { no_world(); }
void World::render_packed(uint8_t*) const { no_world(); }
BevScene World::scene() const { no_world(); }
CameraScene World::camera_scene(double) const { no_world(); }
void World::render_from(const Pose2&, uint8_t*) const { no_world(); }
std::vector<SignalHead> find_signal_heads(const RoadNetwork&) { no_world(); }
std::string World::add_scripted_vehicle(const std::string&, double, double) { no_world(); }
void World::set_vehicle_speed(const std::string&, double) { no_world(); }
std::string World::add_scripted_pedestrian(const std::string&, double) { no_world(); }
void World::place_pedestrian(const std::string&, Vec2) { no_world(); }

}  // namespace cd
