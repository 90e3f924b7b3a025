// Devices (SPEC section 11): what auto, cpu and cuda resolve to on this build and machine, the
// one-line errors, the run record's device fields, and weights that move between devices. On a
// CPU build (CI) the CUDA branches check the errors; on a CUDA machine (scripts/gpu_check.sh)
// they train, save and load on the GPU.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <torch/torch.h>
#include <torch/version.h>

#include "../support/fake_episodes.hpp"
#include "../support/tiny_training.hpp"
#include "core/build_parts.hpp"
#include "core/error.hpp"
#include "datasets/episode_set.hpp"
#include "inference/policy_runner.hpp"
#include "runs/checkpoint.hpp"
#include "device/device.hpp"

namespace cd {
namespace {

using test::TempDir;

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Device, ResolvesAutoCpuAndCudaOrSaysWhatIsMissing) {
  EXPECT_EQ(resolve_device("cpu", "train.device"), "cpu");
  EXPECT_EQ(resolve_device("auto", "train.device"), cuda_usable() ? "cuda" : "cpu");
  if (!torch_built_with_cuda()) {
    EXPECT_FALSE(cuda_usable());
  }
  const std::string bad = error_of([] { resolve_device("gpu", "eval.device"); });
  EXPECT_EQ(bad, "eval.device must be auto, cpu or cuda (got 'gpu')");
  if (cuda_usable()) {
    EXPECT_EQ(resolve_device("cuda", "train.device"), "cuda");
    return;
  }
  const std::string e = error_of([] { resolve_device("cuda", "train.device"); });
  ASSERT_FALSE(e.empty()) << "cuda must be refused where CUDA is not usable";
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  EXPECT_EQ(e.rfind("train.device = \"cuda\", but ", 0), 0u) << e;
  if (torch_built_with_cuda())
    EXPECT_NE(e.find("this machine has no GPU"), std::string::npos) << e;
  else
    EXPECT_NE(e.find(std::string("libtorch ") + TORCH_VERSION + " has no CUDA"),
              std::string::npos)
        << e;
}

TEST(Device, Bf16IsForCudaAndTheRecordNamesEverything) {
  const ComputeDevice cpu = compute_device("cpu", "fp32", false, 3);
  const nlohmann::json r = cpu.record();
  EXPECT_EQ(r.at("device"), "cpu");
  EXPECT_EQ(r.at("precision"), "fp32");
  EXPECT_EQ(r.at("deterministic"), true);
  EXPECT_EQ(r.at("threads"), 3);
  EXPECT_EQ(r.at("libtorch"), TORCH_VERSION);
  if (!torch_built_with_cuda()) {
    EXPECT_EQ(r.at("cuda"), "not built in");
  }
  if (cuda_usable()) {
    EXPECT_NE(r.at("cuda").get<std::string>().find("device(s)"), std::string::npos);
  }
  EXPECT_EQ(error_of([] { compute_device("cpu", "bf16", false, 1); }),
            "train.precision = \"bf16\" runs on CUDA only, and train.device resolved to the CPU "
            "here; use \"fp32\"");
  EXPECT_FALSE(error_of([] { compute_device("cpu", "fp16", false, 1); }).empty());
  if (cuda_usable()) {
    const ComputeDevice gpu = compute_device("cuda", "bf16", true, 1);
    EXPECT_EQ(gpu.record().at("precision"), "bf16");
    EXPECT_EQ(gpu.record().at("deterministic"), true);
    // Autocast runs a matrix product in bf16 inside the scope and in float32 after it.
    const torch::Tensor a = torch::ones({4, 4}, torch::Device(torch::kCUDA));
    {
      AutocastScope scope(gpu);
      EXPECT_EQ(torch::mm(a, a).scalar_type(), torch::kBFloat16);
    }
    EXPECT_EQ(torch::mm(a, a).scalar_type(), torch::kFloat32);
    compute_device("cuda", "fp32", false, 1);  // back to the default mode
  }
}

// A tiny bc-oh run trained with train.device = "auto", on hand-made episodes in dir/data.
std::string train_on_auto(const TempDir& dir) {
  test::write_fake_folder(dir / "data", 3, {.frames = 30});
  Settings s = test::tiny_family_settings();
  s.train.device = "auto";
  return test::train_tiny_run(dir, "bc-oh", "run", s);
}

// A tiny bc-oh run's record says where and how it trained.
TEST(Device, RunRecordNamesDevicePrecisionAndLibtorch) {
  TempDir dir("cd-device");
  const std::string run = train_on_auto(dir);
  std::ifstream in(run + "/checkpoint.json");
  const nlohmann::json ck = nlohmann::json::parse(in);
  const std::string expected = cuda_usable() ? "cuda" : "cpu";
  EXPECT_EQ(ck.at("device"), expected);
  const nlohmann::json& rt = ck.at("runtime");
  EXPECT_EQ(rt.at("device"), expected);
  EXPECT_EQ(rt.at("precision"), "fp32");
  EXPECT_EQ(rt.at("deterministic"), expected == "cpu");
  EXPECT_EQ(rt.at("threads"), 1);
  EXPECT_EQ(rt.at("libtorch"), TORCH_VERSION);
  EXPECT_EQ(ck.at("settings").at("train").at("device"), "auto");
  // The CPU's model, against util-linux's lscpu (its "Model name:" line).
  const test::CommandResult l = test::run_command({"/usr/bin/lscpu"});
  ASSERT_TRUE(l.exited && l.exit_code == 0) << l.describe();
  const std::size_t at = l.out.find("Model name:");
  ASSERT_NE(at, std::string::npos) << l.out;
  const std::size_t from = l.out.find_first_not_of(' ', at + 11);
  EXPECT_EQ(rt.at("cpu"), l.out.substr(from, l.out.find('\n', from) - from));
  EXPECT_NE(rt.at("cpu"), "unknown");
  // ATen's kernels: one of its three on x86 (DispatchStub.h's CPUCapability), never above what
  // the CPU's flags allow.
  const std::string kernels = rt.at("cpu_kernels");
  EXPECT_TRUE(kernels == "DEFAULT" || kernels == "AVX2" || kernels == "AVX512") << kernels;
  const std::string flags = test::read_text("/proc/cpuinfo");
  if (flags.find(" avx2") == std::string::npos) {
    EXPECT_EQ(kernels, "DEFAULT");
  }
  if (flags.find(" avx512f") == std::string::npos) {
    EXPECT_NE(kernels, "AVX512");
  }
}

// Weights saved on one device drive on the other: the run trained where `auto` put it, and its
// best.pt runs on the CPU (a CUDA run evaluated on a CPU machine) and, where there is a GPU, on
// CUDA, with the same actions to float tolerance.
TEST(Device, CheckpointLoadsOnEitherDevice) {
  TempDir dir("cd-device-load");
  const std::string run = train_on_auto(dir);
  const EpisodeSet set = load_episode_set(dir / "data");
  std::vector<std::vector<uint8_t>> frames(3, std::vector<uint8_t>(set.frame_values()));
  std::vector<const uint8_t*> ptrs;
  for (int k = 0; k < 3; ++k) {
    set.planes255(0, 10 + 2 * k, frames[k].data());
    ptrs.push_back(frames[k].data());
  }
  PolicyRunner cpu(run, "bc-oh", kBestFile, "cpu");
  const PolicyStep a = cpu.run(ptrs.data(), 3.0, 0);
  EXPECT_GE(a.throttle, 0.0);
  EXPECT_LE(a.brake, 1.0);
  // The same weights loaded again on auto: on a CPU machine the very same bytes of output.
  PolicyRunner any(run, "bc-oh", kBestFile, "auto");
  const PolicyStep b = any.run(ptrs.data(), 3.0, 0);
  if (cuda_usable()) {
    EXPECT_NEAR(a.throttle, b.throttle, 1e-4);
    EXPECT_NEAR(a.brake, b.brake, 1e-4);
  } else {
    EXPECT_EQ(a.throttle, b.throttle);
    EXPECT_EQ(a.brake, b.brake);
  }
  // eval.device = "cuda" without CUDA: the one-line error at the first step.
  if (!cuda_usable()) {
    PolicyRunner gpu(run, "bc-oh", kBestFile, "cuda");
    EXPECT_THROW(gpu.run(ptrs.data(), 3.0, 0), ConfigError);
  }
}

}  // namespace
}  // namespace cd
