#include "app/build_info.hpp"

#include <torch/cuda.h>
#include <torch/version.h>

#include "core/build_parts.hpp"
#include "core/mpi.hpp"

namespace cd {

std::string cuda_description() {
  if (!torch_built_with_cuda()) return "not built in";
  const size_t n = torch::cuda::is_available() ? torch::cuda::device_count() : 0;
  return n == 0 ? "built in, no device" : std::to_string(n) + " device(s)";
}

std::string build_components() {
  return std::string("libtorch ") + TORCH_VERSION + " (CUDA: " + cuda_description() +
         "), MPI: " + (mpi_compiled() ? "yes" : "no") + ", " + build_parts_description();
}

std::string build_description() { return "causaldrive 0.1.0 (" + build_components() + ")"; }

}  // namespace cd
