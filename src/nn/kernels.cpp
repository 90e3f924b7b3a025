#include "nn/kernels.hpp"

#include <vector>

namespace cd {

namespace {
thread_local bool invariant = false;

bool invariant_on(const torch::Tensor& x) { return invariant && x.device().is_cpu(); }

std::vector<int64_t> vec(const torch::ExpandingArray<2>& a) { return {a->begin(), a->end()}; }
}  // namespace

BatchInvariantKernels::BatchInvariantKernels(bool on) : previous_(invariant) { invariant = on; }
BatchInvariantKernels::~BatchInvariantKernels() { invariant = previous_; }
bool batch_invariant_kernels() { return invariant; }

torch::Tensor conv_forward(torch::nn::Conv2dImpl& conv, const torch::Tensor& x) {
  const auto& o = conv.options;
  // Unqualified, so argument-dependent lookup finds the variant's own get_if: c10's in
  // libtorch 1.x, std's once libtorch's options hold std::variant (2.x).
  const auto* pad = get_if<torch::ExpandingArray<2>>(&o.padding());
  if (!invariant_on(x) || !pad || o.transposed() || x.dim() != 4 || x.size(0) == 1 ||
      x.scalar_type() != torch::kFloat || o.groups() != 1 ||
      !holds_alternative<torch::enumtype::kZeros>(o.padding_mode()))
    return conv.forward(x);
  // The kernel libtorch 1.13 takes for this convolution at batch 1 (ConvParams::use_mkldnn with
  // one row: oneDNN for a kernel larger than 3x3 or a row of more than 20480 values, for a 1x1
  // unstrided convolution only with several threads; otherwise the native one), run on every
  // row: each sums a row in an order of its own, whatever the batch (measured:
  // tests/inference/test_policy_batch.cpp), so every row gets the bytes of batch 1.
  const auto& k = *o.kernel_size();
  const auto& stride = *o.stride();
  const auto& dilation = *o.dilation();
  const bool strided = stride[0] != 1 || stride[1] != 1;
  const bool dilated = dilation[0] != 1 || dilation[1] != 1;
  const bool one_by_one = k[0] == 1 && k[1] == 1;
  const int64_t row_values = x.numel() / x.size(0);
  const bool mkldnn = at::hasMKLDNN() && at::globalContext().userEnabledMkldnn() &&
                      (strided || dilated || !one_by_one || at::get_num_threads() > 1) &&
                      ((k[0] > 3 && k[1] > 3) || row_values > 20480);
  const torch::Tensor bias = o.bias() ? conv.bias : torch::Tensor();
  if (mkldnn)
    return at::mkldnn_convolution(x.contiguous(), conv.weight, bias, vec(*pad), vec(o.stride()),
                                  vec(o.dilation()), 1);
  if (dilated) return conv.forward(x);  // (not a layer of these networks)
  return at::thnn_conv2d(x.contiguous(), conv.weight, vec(o.kernel_size()), bias,
                         vec(o.stride()), vec(*pad));
}

torch::Tensor linear_forward(torch::nn::LinearImpl& linear, const torch::Tensor& x) {
  if (!invariant_on(x) || x.dim() != 2 || x.size(0) == 1) return linear.forward(x);
  std::vector<torch::Tensor> rows;
  rows.reserve(static_cast<size_t>(x.size(0)));
  for (int64_t r = 0; r < x.size(0); ++r) rows.push_back(linear.forward(x.narrow(0, r, 1)));
  return torch::cat(rows, 0);
}

torch::Tensor sequential_forward(torch::nn::SequentialImpl& s, torch::Tensor x) {
  for (auto& m : s) {
    if (auto* c = m.ptr()->as<torch::nn::Conv2dImpl>())
      x = conv_forward(*c, x);
    else if (auto* l = m.ptr()->as<torch::nn::LinearImpl>())
      x = linear_forward(*l, x);
    else if (auto* inner = m.ptr()->as<torch::nn::SequentialImpl>())
      x = sequential_forward(*inner, x);
    else
      x = m.forward(x);
  }
  return x;
}

}  // namespace cd
