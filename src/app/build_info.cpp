#include "app/build_info.hpp"

#include <torch/cuda.h>
#include <torch/version.h>

#include "core/mpi.hpp"

namespace cd {

std::string build_components() {
  std::string cuda = torch::cuda::is_available()
                         ? std::to_string(torch::cuda::device_count()) + " device(s)"
                         : std::string("none");
  return std::string("libtorch ") + TORCH_VERSION + " (CUDA: " + cuda + "), MPI: " +
         (mpi_compiled() ? "yes" : "no");
}

std::string build_description() { return "causaldrive 0.1.0 (" + build_components() + ")"; }

}  // namespace cd
