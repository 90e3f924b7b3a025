#pragma once
// What this binary was built with, for `causaldrive --version`, the run records and the
// benchmarks: the libtorch version and whether its CUDA backend is built in and finds a device,
// whether MPI is compiled in, and the optional parts (core/build_parts.hpp).
#include <string>

namespace cd {

// "not built in" | "built in, no device" | "2 device(s)"
std::string cuda_description();

// "libtorch 1.13.0 (CUDA: not built in), MPI: yes, SUMO: yes, MuJoCo: yes"
std::string build_components();

// "causaldrive 0.1.0 (libtorch 1.13.0 (CUDA: not built in), MPI: yes, SUMO: yes, MuJoCo: yes)"
std::string build_description();

}  // namespace cd
