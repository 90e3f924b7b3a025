#pragma once
// Which CPU kernels a network's forward pass runs on, so that closed-loop inference can batch
// observations without changing any of their actions (issue 46).
//
// libtorch picks a convolution's kernel by the batch size (the native path for a small
// convolution at batch 1, oneDNN from batch 2) and OpenBLAS sums a linear layer's row in
// another order from 5 rows on; each changes the last bits of an action, and a closed loop
// amplifies last bits into other episodes. Under BatchInvariantKernels every layer runs, on
// the whole batch, the kernel libtorch takes for it at batch 1 (convolutions: oneDNN or the
// native one, each summing a row on its own; linear layers: one row at a time). A row's output
// is then the bytes of that row run alone at batch 1, as closed loop always ran it, whatever
// the batch it was served in (tests/inference/test_policy_batch.cpp). Training never sets it.
#include <torch/torch.h>

namespace cd {

// While alive (on this thread), the layers below run batch-invariant kernels on the CPU.
// A tensor on another device runs the usual kernels (their bytes may depend on the batch).
class BatchInvariantKernels {
 public:
  explicit BatchInvariantKernels(bool on = true);
  ~BatchInvariantKernels();
  BatchInvariantKernels(const BatchInvariantKernels&) = delete;
  BatchInvariantKernels& operator=(const BatchInvariantKernels&) = delete;

 private:
  bool previous_;
};
bool batch_invariant_kernels();

// A layer's forward on the kernels in force (the module's own forward otherwise).
torch::Tensor conv_forward(torch::nn::Conv2dImpl& conv, const torch::Tensor& x);
torch::Tensor linear_forward(torch::nn::LinearImpl& linear, const torch::Tensor& x);
// Each module of `s` in turn; its convolutions and linear layers as above.
torch::Tensor sequential_forward(torch::nn::SequentialImpl& s, torch::Tensor x);

}  // namespace cd
