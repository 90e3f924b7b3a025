// MuJoCo-Image in a build without MuJoCo (CMakeLists.txt: -DCD_WITH_MUJOCO=OFF): naming an
// environment is the one-line MissingPart error of core/build_parts.hpp. Training on recorded
// MuJoCo-Image episodes needs no simulator and works as in a full build. No Env exists in such a
// build, so its other members are never reached; they are defined for the linker.
#include "core/build_parts.hpp"
#include "mujoco/env.hpp"

namespace cd::mj {

class OffscreenRenderer {};  // renderer.cpp is left out with MuJoCo

namespace {

[[noreturn]] void no_mujoco() {
  require_mujoco("a MuJoCo-Image environment");
  throw MissingPart("no MuJoCo");
}

}  // namespace

const EnvSpec& env_spec(const std::string&) { no_mujoco(); }
std::vector<std::string> env_names() { no_mujoco(); }
std::string assets_dir(const std::string&) { no_mujoco(); }
ModelPtr load_model(const std::string&) { no_mujoco(); }
void install_error_handlers() {}

Env::Env(const std::string& name, const EnvOptions&) : spec_(env_spec(name)) {}
Env::~Env() = default;
double Env::dt() const { no_mujoco(); }
int Env::action_dim() const { no_mujoco(); }
int Env::state_dim() const { no_mujoco(); }
int Env::qpos_dim() const { no_mujoco(); }
std::vector<double> Env::action_low() const { no_mujoco(); }
std::vector<double> Env::action_high() const { no_mujoco(); }
Frame Env::reset(uint64_t) { no_mujoco(); }
StepResult Env::step(std::span<const double>) { no_mujoco(); }
std::vector<double> Env::state() const { no_mujoco(); }
void Env::set_state(std::span<const double>) { no_mujoco(); }
std::vector<double> Env::snapshot() const { no_mujoco(); }
void Env::restore(std::span<const double>) { no_mujoco(); }
void Env::render(uint8_t*) { no_mujoco(); }
Frame Env::render() { no_mujoco(); }

}  // namespace cd::mj
