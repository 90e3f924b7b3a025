#pragma once
// SUMO prints its errors to stderr and throws a bare "Process Error". This captures stderr
// around a call so the World can throw one SimError line that says what went wrong.
#include <functional>
#include <string>

namespace cd {

// Runs `fn` with stderr captured; on any exception throws
// SimError("<context>: <SUMO's first error line>"). For loading and resets, not per step.
void with_sumo_errors(const std::string& context, const std::function<void()>& fn);

// Runs `fn`; turns any exception into SimError("<context>: <what>"). Cheap: for hot paths.
template <class Fn>
void sumo_call(const std::string& context, Fn&& fn);

[[noreturn]] void throw_sim_error(const std::string& context, const std::exception& e);

template <class Fn>
void sumo_call(const std::string& context, Fn&& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    throw_sim_error(context, e);
  }
}

}  // namespace cd
