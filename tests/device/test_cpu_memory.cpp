// Large CPU tensors on huge pages (device/cpu_memory.hpp): where their memory lies and what the
// kernel was told about it, read back from /proc/self/smaps, and the same numbers either way.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>

#include <c10/core/CPUAllocator.h>
#include <torch/torch.h>

#include "device/cpu_memory.hpp"

namespace cd {
namespace {

// The VmFlags of the mapping that holds `p` ("" when no mapping does).
std::string vm_flags_at(const void* p) {
  const auto a = reinterpret_cast<uintptr_t>(p);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line.substr(8) + " ";
  }
  return "";
}

bool advised_huge(const torch::Tensor& t) {
  return vm_flags_at(t.data_ptr()).find(" hg ") != std::string::npos;
}

class HugePages : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(use_huge_pages_for_cpu_tensors()); }
  void TearDown() override { set_huge_pages(true); }
};

TEST_F(HugePages, ALargeTensorIsAlignedAndAdvisedASmallOneIsNot) {
  const torch::Tensor big = torch::ones({4, 1024, 1024});  // 16 MiB
  EXPECT_EQ(reinterpret_cast<uintptr_t>(big.data_ptr()) % kHugePageBytes, 0u);
  EXPECT_TRUE(advised_huge(big)) << vm_flags_at(big.data_ptr());
  EXPECT_EQ(big.sum().item<double>(), 4.0 * 1024 * 1024);
  const torch::Tensor small = torch::ones({1000});  // 4 kB: torch's own allocator
  EXPECT_FALSE(advised_huge(small)) << vm_flags_at(small.data_ptr());
  const torch::Tensor edge = torch::ones({int64_t(kHugePageBytes / 4)});  // exactly 2 MiB
  EXPECT_TRUE(advised_huge(edge));
}

TEST_F(HugePages, SwitchedOffALargeTensorIsNotAdvised) {
  set_huge_pages(false);
  EXPECT_FALSE(huge_pages_on());
  const torch::Tensor big = torch::ones({4, 1024, 1024});
  EXPECT_FALSE(advised_huge(big)) << vm_flags_at(big.data_ptr());
  set_huge_pages(true);
  const torch::Tensor again = torch::ones({4, 1024, 1024});
  EXPECT_TRUE(advised_huge(again));
  // the tensor made while off is freed by its own deleter after the switch: no crash, no leak
}

// A training step's numbers do not depend on where its tensors lie: a conv net's loss and
// gradients, with large activations, byte for byte with the switch off and on.
TEST_F(HugePages, ATrainingStepGivesTheSameBytesEitherWay) {
  auto run = [](bool on) {
    set_huge_pages(on);
    torch::manual_seed(7);
    torch::nn::Sequential net(torch::nn::Conv2d(torch::nn::Conv2dOptions(3, 32, 3).padding(1)),
                              torch::nn::ReLU(), torch::nn::AdaptiveAvgPool2d(1),
                              torch::nn::Flatten(), torch::nn::Linear(32, 2));
    const torch::Tensor x = torch::rand({64, 3, 80, 96});  // activations: 64 x 32 x 80 x 96 floats
    const torch::Tensor loss = net->forward(x).pow(2).mean();
    loss.backward();
    std::vector<torch::Tensor> out{loss.detach().clone()};
    for (const auto& p : net->parameters()) out.push_back(p.grad().clone());
    return out;
  };
  const auto off = run(false), on = run(true);
  ASSERT_EQ(off.size(), on.size());
  for (size_t i = 0; i < off.size(); ++i) EXPECT_TRUE(torch::equal(off[i], on[i])) << i;
}

}  // namespace
}  // namespace cd
