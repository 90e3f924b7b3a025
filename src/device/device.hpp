#pragma once
// Where the networks run (SPEC section 11): train.device, eval.device and [mujoco] sac_device =
// auto | cpu | cuda, resolved once per process; the precision of the forward passes (bf16 autocast
// on CUDA); and CUDA's deterministic mode.
//
// A process that forks workers (eval, collect) must not touch CUDA before it forks: a child of a
// process with a CUDA context cannot use CUDA. cuda_usable() therefore asks in a child process of
// its own, and the parent stays free of CUDA.
#include <string>

#include <c10/core/Device.h>  // torch::Device, without the rest of torch (build time)
#include <nlohmann/json.hpp>

namespace cd {

// Does this build's libtorch have CUDA and this machine a GPU it can use? Asked once, in a child
// process (see above); false at once for a CPU-only libtorch.
bool cuda_usable();

// "cpu" or "cuda" for a setting's value `wanted` (auto | cpu | cuda). `key` names the setting in
// the errors ("train.device"): one line saying whether the build or the machine lacks CUDA.
std::string resolve_device(const std::string& wanted, const std::string& key);

c10::Device torch_device(const std::string& resolved);  // "cpu" | "cuda"

// The CPU's model as the kernel names it (/proc/cpuinfo's first "model name"), or "unknown"
// where it does not say (not Linux, or an architecture that names it otherwise).
std::string cpu_model();

// The vector kernels ATen picks on this CPU: DEFAULT, AVX2 or AVX512 (or "unknown").
std::string cpu_kernels();

// Where a run trains, with what it needs to say in its record.
struct ComputeDevice {
  std::string name = "cpu";  // cpu | cuda
  c10::Device device = c10::DeviceType::CPU;
  std::string precision = "fp32";  // fp32 | bf16 (CUDA only)
  bool deterministic = true;       // the CPU always; CUDA when train.cuda_deterministic
  int threads = 1;                 // torch's intra-op threads
  // {"device", "precision", "deterministic", "threads", "libtorch", "cuda", "cpu",
  // "cpu_kernels"}: the run record's "runtime" (libtorch's version; CUDA as build_info's
  // cuda_description, or the GPU's name; the CPU's model and ATen's kernels for it). Same seed,
  // same bytes holds per CPU model: libtorch picks its kernels by the CPU's instruction set, so
  // two CPUs can round differently.
  nlohmann::json record() const;
};

// train.device, train.precision and train.cuda_deterministic resolved (`key` names the device
// setting in errors): a ConfigError for bf16 on the CPU. Sets CUDA's deterministic or benchmark
// mode for the process.
ComputeDevice compute_device(const std::string& device, const std::string& precision,
                             bool cuda_deterministic, int threads,
                             const std::string& key = "train.device");

// Runs the forward passes of its scope under bf16 autocast when `device` asks for it (CUDA,
// precision bf16); otherwise does nothing. Weights and gradients stay float32.
class AutocastScope {
 public:
  explicit AutocastScope(const ComputeDevice& device);
  ~AutocastScope();
  AutocastScope(const AutocastScope&) = delete;
  AutocastScope& operator=(const AutocastScope&) = delete;

 private:
  bool on_ = false;
};

}  // namespace cd
