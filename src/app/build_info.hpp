#pragma once
// What this binary was built with, for `causaldrive --version` and the benchmarks: the
// libtorch version and whether it can use CUDA here, and whether MPI is compiled in.
#include <string>

namespace cd {

// "libtorch 1.13.0 (CUDA: none), MPI: yes"
std::string build_components();

// "causaldrive 0.1.0 (libtorch 1.13.0 (CUDA: none), MPI: yes)"
std::string build_description();

}  // namespace cd
