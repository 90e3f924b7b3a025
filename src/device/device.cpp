#include "device/device.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include <ATen/Context.h>
#include <ATen/Version.h>
#include <ATen/autocast_mode.h>
#include <torch/cuda.h>
#include <torch/version.h>

#include "app/build_info.hpp"
#include "core/build_parts.hpp"
#include "core/error.hpp"
#include "core/process.hpp"

// libtorch 2.4 named autocast's state per device type; 1.13 (Debian 12's) had CUDA's alone.
#if TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 4)
#define CD_AUTOCAST_PER_DEVICE 1
#else
#define CD_AUTOCAST_PER_DEVICE 0
#endif

namespace cd {

bool cuda_usable() {
  if (!torch_built_with_cuda()) return false;
  static const bool usable = [] {
    const pid_t pid = fork();
    if (pid == 0) _exit(torch::cuda::is_available() && torch::cuda::device_count() > 0 ? 0 : 1);
    if (pid < 0) return false;
    // -1: its status is lost (SIGCHLD ignored by a host process): no GPU is assumed.
    const int status = wait_child(pid);
    return status >= 0 && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  }();
  return usable;
}

std::string resolve_device(const std::string& wanted, const std::string& key) {
  if (wanted == "cpu") return "cpu";
  if (wanted == "auto") return cuda_usable() ? "cuda" : "cpu";
  if (wanted != "cuda")
    throw ConfigError(key + " must be auto, cpu or cuda (got '" + wanted + "')");
  if (!torch_built_with_cuda())
    throw ConfigError(key + " = \"cuda\", but this build's libtorch " + TORCH_VERSION +
                      " has no CUDA (build against a CUDA libtorch: docs/gpu.md); use \"cpu\" "
                      "or \"auto\"");
  if (!cuda_usable())
    throw ConfigError(key + " = \"cuda\", but this machine has no GPU that CUDA can use (libtorch " +
                      TORCH_VERSION + " has CUDA); use \"cpu\" or \"auto\"");
  return "cuda";
}

c10::Device torch_device(const std::string& resolved) {
  return resolved == "cuda" ? c10::Device(c10::DeviceType::CUDA) : c10::Device(c10::DeviceType::CPU);
}

std::string cpu_model() {
  static const std::string model = [] {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("model name", 0) != 0) continue;
      const std::size_t colon = line.find(':');
      if (colon == std::string::npos) break;
      const std::size_t start = line.find_first_not_of(" \t", colon + 1);
      if (start == std::string::npos) break;
      return line.substr(start, line.find_last_not_of(" \t") + 1 - start);
    }
    return std::string("unknown");
  }();
  return model;
}

// The vector kernels ATen dispatches to on this CPU (DEFAULT, AVX2, AVX512), from the line
// "CPU capability usage: X" of at::show_config() (libtorch does not export the query itself).
std::string cpu_kernels() {
  static const std::string kernels = [] {
    const std::string config = at::show_config(), key = "CPU capability usage: ";
    const std::size_t at = config.find(key);
    if (at == std::string::npos) return std::string("unknown");
    const std::size_t from = at + key.size();
    return config.substr(from, config.find_first_of("\r\n", from) - from);
  }();
  return kernels;
}

nlohmann::json ComputeDevice::record() const {
  return {{"device", name},          {"precision", precision}, {"deterministic", deterministic},
          {"threads", threads},      {"libtorch", TORCH_VERSION},
          {"cuda", cuda_description()}, {"cpu", cpu_model()}, {"cpu_kernels", cpu_kernels()}};
}

ComputeDevice compute_device(const std::string& device, const std::string& precision,
                             bool cuda_deterministic, int threads, const std::string& key) {
  ComputeDevice d;
  d.name = resolve_device(device, key);
  d.device = torch_device(d.name);
  d.threads = threads;
  if (precision != "fp32" && precision != "bf16")
    throw ConfigError("train.precision must be fp32 or bf16 (got '" + precision + "')");
  if (precision == "bf16" && d.name != "cuda")
    throw ConfigError("train.precision = \"bf16\" runs on CUDA only, and train.device resolved "
                      "to the CPU here; use \"fp32\"");
  d.precision = precision;
  if (d.name == "cuda") {
    d.deterministic = cuda_deterministic;
    if (cuda_deterministic) {
      // cuBLAS is deterministic only with a fixed workspace, set before its first handle.
      setenv("CUBLAS_WORKSPACE_CONFIG", ":4096:8", 0);
      at::globalContext().setDeterministicAlgorithms(true, false);
    }
    at::globalContext().setDeterministicCuDNN(cuda_deterministic);
    at::globalContext().setBenchmarkCuDNN(!cuda_deterministic);
  }
  return d;
}

AutocastScope::AutocastScope(const ComputeDevice& device)
    : on_(device.name == "cuda" && device.precision == "bf16") {
  if (!on_) return;
#if CD_AUTOCAST_PER_DEVICE
  at::autocast::set_autocast_dtype(at::kCUDA, at::kBFloat16);
  at::autocast::set_autocast_enabled(at::kCUDA, true);
#else
  at::autocast::set_autocast_gpu_dtype(at::kBFloat16);
  at::autocast::set_enabled(true);
#endif
  at::autocast::increment_nesting();
}

AutocastScope::~AutocastScope() {
  if (!on_) return;
  if (at::autocast::decrement_nesting() == 0) at::autocast::clear_cache();
#if CD_AUTOCAST_PER_DEVICE
  at::autocast::set_autocast_enabled(at::kCUDA, false);
#else
  at::autocast::set_enabled(false);
#endif
}

}  // namespace cd
